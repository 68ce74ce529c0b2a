/* SPDX-License-Identifier: BSD-3-Clause */
// What eucsbademo and balsba say about a solve beyond sba 1.6's summary: the lines a user reads
// first (RMS reprojection error in pixels, the stop reason in words, the solver and threads
// that ran, the time) and the same as one JSON object for pipelines (--json FILE).
#ifndef SBA_DEMO_REPORT_H
#define SBA_DEMO_REPORT_H

#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "cli/run_control.h"
#include "sba.h"
#include "sba_ext.h"

namespace sbaformats {
class OutputSet;  // formats/output_file.h
}  // namespace sbaformats

namespace sbacli {

// One camera's share of the final residuals, in pixels (not weighted by covariances).
struct CameraResidual {
  long long observations = 0;
  double sum_sq = 0;  // sum of the squared pixel distances of its projections
  std::string name;   // its image, when the input names it; empty: not named
};

struct Report {
  std::string program;
  std::vector<std::string> inputs;  // the files read
  // What the input was refined as, in words (sbarefine: the camera models and which of their
  // parameters are refined); empty: not written.
  std::string model;
  // sizes
  int cameras = 0, points = 0;
  // variables: the parameters as sba 1.6 counts them (every camera's and every point's, held
  // ones and each copy of a shared one included); unknowns: what the solve estimates (-1: not
  // counted, and not written).
  long long observations = 0, variables = 0, unknowns = -1;
  // options
  std::string solver_requested;  // what was asked ("auto": the library chose); empty: the library's default
  std::string strategy_requested;  // empty: the library's choice
  int threads_requested = 0;     // 0: the library's choice
  bool avoid_shared_cores = false;  // sba_ext_options.avoid_shared_cores, or the environment's
  int itmax = 0;
  std::array<double, 5> opts{};
  std::string loss;  // empty: least squares
  double loss_scale = 1.0;
  int mcon = 0, ncon = 0;
  double max_time = 0;
  bool single_jacobian = false;  // the Jacobian stored in single precision
  // result
  int ret = SBA_ERROR;
  std::array<double, SBA_INFOSZ> info{};
  sba_ext_result result{};
  double seconds = 0;  // the solve, as the 1.6 "Elapsed time" line
  std::vector<RunControl::Iteration> iterations;
  std::vector<CameraResidual> per_camera;
  // The priors of the solve (sba_ext.h); with some, the costs apart are reported.
  int priors = 0;
  // COLMAP's mean reprojection error in pixels, initial and final (mean_error_by_point,
  // solve_options.h); NaN: not reported.
  double mean_initial = NAN, mean_final = NAN;

  // Root mean square of the projections' pixel distances, from the plain squared errors.
  double rms_initial() const;
  double rms_final() const;
};

// The stop reason info[6] in words: sba_stop_reason_text's, with what stops these programs on
// request.
std::string stop_reason_text(int reason);

// The lines printed after sba 1.6's summary: the RMS error (and COLMAP's mean error, when the
// report has it), the stop reason, the solver.
void print_report(std::FILE *out, const Report &r);

// What a run's outputs removed when they were published (OutputSet::removed), a line for each
// reason: "Removed WHAT (PATH, PATH ...): WHY".
void print_removed(std::FILE *out, const sbaformats::OutputSet &outputs);

// Writes the report as one JSON object to path (whole or not at all, see output_file.h; with
// `outputs`, when that set of the run's outputs is committed): false with "PATH: why" in *error
// if it cannot.
bool write_json(const std::string &path, const Report &r, std::string *error,
                sbaformats::OutputSet *outputs = nullptr);

}  // namespace sbacli

#endif  // SBA_DEMO_REPORT_H
