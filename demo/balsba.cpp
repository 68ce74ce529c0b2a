// SPDX-License-Identifier: BSD-3-Clause
// balsba: bundle adjustment of a BAL problem file (plain or .bz2) with sba's expert
// motion-and-structure driver and the BAL camera model's analytic Jacobian.
#include <array>
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

#include "bal_io.h"
#include "bal_model.h"
#include "cli.h"
#include "output_file.h"
#include "report.h"
#include "run_control.h"
#include "solve_options.h"
#include "sba.h"
#include "sba_ext.h"
#include "tty_progress.h"

namespace {

using sbacli::kExitFailure;
using sbacli::kExitUsage;

struct Options {
  std::string file;
  sbademo::SolveOptions solve;
  std::string write;
  bool help = false, version = false;
};

std::vector<sbacli::Option> option_table(Options &o) {
  std::vector<sbacli::Option> t;
  sbademo::add_solve_options(
      &t, o.solve,
      {"write", "OUT", "write the refined problem in BAL format (OUT ending in .bz2: compressed)",
       [&o](const std::string &v) { return sbacli::to_file(v, &o.write); }});
  return t;
}

bool parse_command_line(int argc, char **argv, Options *options, std::string *error) {
  Options o;
  if (!sbademo::parse_one_input(argc, argv, option_table(o), "file argument (a BAL problem)", &o.file, &o.help,
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
  if (const int status = sbademo::answer_command_line("balsba", parsed, error, o.help, o.version, print_usage);
      status >= 0)
    return status;
  sbademo::SolveOptions &so = o.solve;
  if (!sbademo::outputs_writable({&o.write, &so.json})) return kExitFailure;

  const auto read_start = std::chrono::steady_clock::now();
  bal::Problem problem;
  bal::SbaLayout s;
  if (!bal::read_problem(o.file, &problem, &error) || !bal::to_sba(problem, o.file, &s, &error)) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return kExitFailure;
  }
  const double read_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - read_start).count();
  if (so.mcon > s.m) {
    std::fprintf(stderr, "balsba: --mcon %d is more than the %d cameras\n", so.mcon, s.m);
    return kExitUsage;
  }
  if (so.ncon > s.n) {
    std::fprintf(stderr, "balsba: --ncon %d is more than the %d points\n", so.ncon, s.n);
    return kExitUsage;
  }

  // The BAL callbacks are re-entrant and walk the index by rows: the threads share them.
  sbademo::LogSink sink;
  sba_ext_result result;
  sba_ext_options ext;
  sbademo::init_ext(so, &sink, &result, &ext);

  bal::CallbackData data;
  data.ncameras = s.m;
  std::array<double, SBA_INFOSZ> info{};
  const int nobs = s.nobservations();
  sbademo::TtyProgress progress(so.progress, nobs);
  sbademo::RunControl control(so.max_time, &progress);
  sbademo::RunControl::catch_signals();
  control.attach(&ext);
  const auto start = std::chrono::steady_clock::now();
  const int ret = sba_motstr_levmar_x_ext(s.n, so.ncon, s.m, so.mcon, s.vmask.data(), s.p.data(), bal::kCameraParams,
                                          bal::kPointParams, s.x.data(), nullptr, bal::kMeasurementParams,
                                          bal::motstr_func, bal::motstr_fjac, &data, so.itmax, so.verbose,
                                          so.opts.data(), info.data(), &ext);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  progress.finish();
  if (ret == SBA_ERROR) {
    std::fprintf(stderr, "balsba: %s: the solve failed (SBA_ERROR, reason %g): %s\n", o.file.c_str(), info[6],
                 sink.first_error.empty() ? "no result" : sink.first_error.c_str());
    return kExitFailure;
  }

  if (!o.write.empty()) {
    bal::from_sba_params(s.p.data(), &problem);
    if (!bal::write_problem(o.write, problem, &error)) {
      std::fprintf(stderr, "%s\n", error.c_str());
      return kExitFailure;
    }
  }

  const long long nvars = static_cast<long long>(s.m) * bal::kCameraParams +
                          static_cast<long long>(s.n) * bal::kPointParams;
  std::printf("BAL problem %s: %d cameras, %d points, %d observations, %lld variables\n", o.file.c_str(),
              s.m, s.n, nobs, nvars);
  sbademo::print_summary(nobs, ret, info, seconds, read_seconds, result, so);

  sbademo::Report report = sbademo::make_report("balsba", o.file, s.m, s.n, nobs, nvars, so, ret, info, result,
                                                seconds, control);
  sbademo::print_report(stdout, report);
  if (!so.json.empty()) {
    const double *points = s.p.data() + static_cast<std::size_t>(s.m) * bal::kCameraParams;
    sbademo::add_per_camera(
        s.n, s.m, s.vmask.data(), s.x.data(),
        [&](int j, int i, double x[2]) {
          bal::project(s.p.data() + static_cast<std::size_t>(j) * bal::kCameraParams,
                       points + static_cast<std::size_t>(i) * bal::kPointParams, x);
        },
        &report);
    if (!sbademo::write_json(so.json, report, &error)) {
      std::fprintf(stderr, "%s: %s\n", so.json.c_str(), error.c_str());
      return kExitFailure;
    }
  }
  if (!o.write.empty()) std::printf("Wrote %s\n", o.write.c_str());
  // A stopped solve is a result (written above), but the status says it was cut short by a
  // signal; a time limit the user set is an ordinary end.
  if (info[6] == SBA_STOP_USER)
    return sbademo::stopped_status("balsba", control, so.max_time, static_cast<int>(info[5]));
  return 0;
}

}  // namespace

int main(int argc, char **argv) { return sbademo::guarded_main("balsba", bal_main, argc, argv); }
