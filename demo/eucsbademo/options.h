/* SPDX-License-Identifier: BSD-3-Clause */
// eucsbademo's command line: the sba 1.6 positional arguments plus GNU-style long options for
// everything 1.6 fixed at compile time. Defaults are 1.6's.
#ifndef SBA_DEMO_EUCSBADEMO_OPTIONS_H
#define SBA_DEMO_EUCSBADEMO_OPTIONS_H

#include <array>
#include <cstdio>
#include <string>
#include <vector>

#include "cli/cli.h"

namespace eucsbademo {

// 1.6's "howto": what is refined.
enum class RefineMode {
  MotionStructure,          // BA_MOTSTRUCT
  Motion,                   // BA_MOT
  Structure,                // BA_STRUCT
  MotionThenMotionStructure // BA_MOT_MOTSTRUCT: motion, then both if the error stays high
};

struct DemoOptions {
  RefineMode refine = RefineMode::MotionStructure;
  bool expert = true;           // expert (func/fjac) or simple (proj/projac) driver
  bool single_jacobian = false;  // the Jacobian stored in single precision (simple driver)
  bool analytic = true;         // analytic Jacobian, or finite differences (fjac/projac NULL)
  int itmax = -1;               // -1: 150 for motion+structure, 100 for motion or structure
  std::array<double, 5> opts{1e-3, 1e-12, 1e-12, 1e-12, 0.0};  // tau, eps1..eps4
  int verbose = 0;
  int mcon = 0, ncon = 0;       // leading cameras / points held fixed
  int nccalib = 2, ncdist = 3;  // trailing intrinsics / distortion terms held fixed
  bool held_given = false;      // --nccalib or --ncdist on the command line
  bool check_jacobian = false;  // itmax 0: the library compares fjac with finite differences
  std::string linsolver;        // one of sba_linsolver_names(); empty: the library's choice
                                // (SBA_LINSOLVER if set, else chol)
  std::string strategy;         // one of sba_strategy_names(); empty: the library's choice
                                // (SBA_STRATEGY if set, else sba)
  int nthreads = 0;             // 0: the library's choice (SBA_NUM_THREADS, else by problem size)
  std::string loss;             // robust loss (sba_ext.h names); empty: least squares
  double loss_scale = 1.0;      // its scale, in pixels
  bool progress = true;         // one-line progress on stderr when it is a terminal
  double max_time = 0;          // stop after the iteration that ends past this many seconds; 0: none
  std::string write_stddev;     // per-camera and per-point standard deviations; empty: none
  std::string write_cams, write_pts, write_pts_tracks;  // empty: not written
  std::string json;             // the run as one JSON object; empty: not written
  std::string initial_ply, final_ply;  // points and camera centres before and after; empty: not written
  std::vector<std::string> files;  // cams.txt pts.txt [calib.txt]
  bool help = false, version = false;
};

// Parses argv. On error returns false with a one-line message (no program name, no newline).
// With --help or --version it returns true without requiring the file arguments.
bool parse_command_line(int argc, const char *const *argv, DemoOptions *options, std::string *error);

// Largest --threads value accepted (the same in every program).
constexpr int kMaxThreads = sbacli::kMaxThreads;

// The --help text.
void print_usage(std::FILE *out);

}  // namespace eucsbademo

#endif  // SBA_DEMO_EUCSBADEMO_OPTIONS_H
