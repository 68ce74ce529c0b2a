// SPDX-License-Identifier: BSD-3-Clause
// balsba: bundle adjustment of a BAL problem file (plain or .bz2) with sba's expert
// motion-and-structure driver and the BAL camera model's analytic Jacobian.
#include <cerrno>
#include <chrono>
#include <cmath>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <limits>
#include <new>
#include <string>
#include <vector>

#include "cameras/bal_camera.h"
#include "cameras/camera_pose.h"
#include "cli/cli.h"
#include "cli/motstr_solve.h"
#include "cli/ply_options.h"
#include "cli/solve_options.h"
#include "formats/bal_io.h"
#include "formats/output_file.h"
#include "sba.h"
#include "sba_ext.h"

namespace bal = sbaformats::bal;
namespace bal_camera = sbacameras::bal;

namespace {

using sbacli::kExitFailure;

struct Options {
  std::string file;
  sbacli::SolveOptions solve;
  std::string write;
  std::string initial_ply, final_ply;
  bool single_jacobian = false;
  bool help = false, version = false;
};

std::vector<sbacli::Option> option_table(Options &o) {
  std::vector<sbacli::Option> t;
  sbacli::add_solve_options(
      &t, o.solve,
      {"write", "OUT", "write the refined problem in BAL format (OUT ending in .bz2: compressed)",
       [&o](const std::string &v) { return sbacli::to_file(v, &o.write); }});
  sbacli::add_ply_options(&t, &o.initial_ply, &o.final_ply, false);
  t.push_back({"single-precision-jacobian", "",
               "store the Jacobian in single precision and keep no residual: about 0.6x the memory\n"
               "(the simple driver, per-projection callbacks; not with --solver=ldl-amd)",
               [&o](const std::string &) {
                 o.single_jacobian = true;
                 return std::string();
               }});
  return t;
}

// The points and camera centres of a BAL problem, which has no colors.
sbaformats::Cloud cloud(const bal::Problem &problem) {
  sbaformats::Cloud c;
  for (int i = 0; i < problem.npoints; ++i) {
    const double *x = problem.point(i);
    c.points.push_back({x[0], x[1], x[2]});
  }
  for (int j = 0; j < problem.ncameras; ++j) {
    const double *a = problem.camera(j);
    double R[9];
    bal_camera::rotation_matrix(a, R);
    c.centres.push_back(sbacameras::camera_centre(R, a + 3));
  }
  return c;
}

bool parse_command_line(int argc, char **argv, Options *options, std::string *error) {
  Options o;
  if (!sbacli::parse_one_input(argc, argv, option_table(o), "file argument (a BAL problem)", &o.file, &o.help,
                                &o.version, error))
    return false;
  *options = std::move(o);
  return true;
}

void print_usage(std::FILE *out) {
  std::fputs(
      "Usage: balsba [OPTION]... FILE\n"
      "Bundle-adjusts a BAL problem (\"Bundle Adjustment in the Large\": plain text, or .bz2)\n"
      "with sba_motstr_levmar_x_ext: cameras (Rodrigues rotation, translation, f, k1, k2) and\n"
      "points, analytic Jacobian.\n"
      "\n"
      "Options (a value may follow as --opt=VALUE or --opt VALUE; '--' ends the options):\n",
      out);
  Options scratch;
  sbacli::print_options(out, option_table(scratch));
  std::fprintf(out, "\nLinear solvers (--solver): %s\n", sba_linsolver_names());
  std::fputs(
      "\n"
      "Prints the sizes, sba 1.6's summary (mean squared reprojection error in pixels^2 per\n"
      "observation, iterations, stop reason, evaluations, the solve time), then the RMS\n"
      "reprojection error in pixels, the stop reason in words, the solver and threads used.\n"
      "Exit status: 0 done (--max-time included), 1 a file cannot be read or written or the solver\n"
      "fails, 2 bad options, 130 (SIGINT) or 143 (SIGTERM) when a signal stopped the solve.\n",
      out);
}

int bal_main(int argc, char **argv) {
  Options o;
  std::string error;
  const bool parsed = parse_command_line(argc, argv, &o, &error);
  if (const int status = sbacli::answer_command_line("balsba", parsed, error, o.help, o.version, print_usage);
      status >= 0)
    return status;
  sbacli::SolveOptions &so = o.solve;
  if (!sbacli::outputs_writable({&o.write, &so.json, &o.initial_ply, &o.final_ply})) return kExitFailure;

  const auto read_start = std::chrono::steady_clock::now();
  bal::Problem problem;
  bal::SbaLayout s;
  if (!bal::read_problem(o.file, &problem, &error) || !bal::to_sba(problem, o.file, &s, &error)) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return kExitFailure;
  }
  const double read_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - read_start).count();
  sbacli::MotstrInputs in;
  in.n = s.n;
  in.m = s.m;
  in.cnp = bal_camera::kCameraParams;
  in.pnp = bal_camera::kPointParams;
  in.vis = &s.vis;
  in.p = s.p.data();
  in.x = s.x.data();
  in.func = bal_camera::motstr_func;
  in.fjac = bal_camera::motstr_fjac;
  in.proj = bal_camera::motstr_proj;
  in.projac = bal_camera::motstr_projac;
  in.single_jacobian = o.single_jacobian;
  bal_camera::CallbackData data;
  data.ncameras = s.m;
  in.adata = &data;
  sbacli::MotstrSolve solve("balsba", o.file, so, in);
  if (const int status = solve.check_fixed(); status >= 0) return status;
  // Every file of the run is published at its end, together, or none is (output_file.h).
  sbaformats::OutputSet outputs;
  if (!sbacli::write_ply_option(o.initial_ply, cloud(problem), &outputs)) return kExitFailure;
  if (!solve.run()) return kExitFailure;

  bal::from_sba_params(s.p.data(), &problem);
  if (!o.write.empty() &&
      !outputs.publish_last([&] { return bal::write_problem(o.write, problem, &error, &outputs); })) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return kExitFailure;
  }
  if (!sbacli::write_ply_option(o.final_ply, cloud(problem), &outputs)) return kExitFailure;

  std::printf("BAL problem %s: %d cameras, %d points, %d observations, %lld variables\n", o.file.c_str(), s.m, s.n,
              solve.observations(), solve.variables());
  const double *points = s.p.data() + static_cast<std::size_t>(s.m) * bal_camera::kCameraParams;
  return solve.finish(
      read_seconds,
      [&](int j, int i, double x[2]) {
        bal_camera::project(s.p.data() + static_cast<std::size_t>(j) * bal_camera::kCameraParams,
                     points + static_cast<std::size_t>(i) * bal_camera::kPointParams, x);
      },
      {}, o.write, &outputs);
}

}  // namespace

int main(int argc, char **argv) { return sbacli::guarded_main("balsba", bal_main, argc, argv); }
