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
#include "sba.h"
#include "sba_ext.h"
#include "tty_progress.h"

namespace {

using sbacli::kExitFailure;
using sbacli::kExitUsage;

struct Options {
  std::string file;
  std::string solver;  // empty: the library's default
  std::string strategy;  // empty: the library's default (SBA_STRATEGY, else sba)
  int threads = 0;
  int itmax = 150;
  std::array<double, 5> opts{1e-3, 1e-12, 1e-12, 1e-12, 0.0};  // sba 1.6's defaults
  int verbose = 0;
  int mcon = 0, ncon = 0;
  std::string write;
  std::string loss;  // empty: least squares
  double loss_scale = 1.0;
  bool progress = true;
  double max_time = 0;  // 0: no limit
  std::string json;     // the run as one JSON object; empty: not written
  bool help = false, version = false;
};

std::vector<sbacli::Option> option_table(Options &o) {
  const int kIntMax = std::numeric_limits<int>::max();
  std::vector<sbacli::Option> t;
  t.push_back({"solver", "NAME",
               "linear solver of the normal equations, one of those listed below (default:\n"
               "the environment variable SBA_LINSOLVER if set, else chol)",
               [&o](const std::string &v) { return sbacli::to_linsolver(v, &o.solver); }});
  t.push_back({"strategy", "NAME",
               "how LM damps, accepts steps and stops: sba (sba 1.6's algorithm, the default) or\n"
               "trust-region (Marquardt's scaled damping and a relative cost tolerance: usually far\n"
               "fewer iterations); default: the environment variable SBA_STRATEGY if set, else sba",
               [&o](const std::string &v) { return sbacli::to_strategy(v, &o.strategy); }});
  t.push_back({"threads", "N",
               "threads; 0 (the default): SBA_NUM_THREADS if set, else every hardware thread, but at\n"
               "most one per 10,000 observations. The result does not depend on it",
               [&o](const std::string &v) { return sbacli::to_threads(v, &o.threads); }});
  t.push_back({"itmax", "N", "maximum iterations (default 150)",
               [&o](const std::string &v) { return sbacli::to_int(v, 0, kIntMax, &o.itmax); }});
  sbacli::add_lm_options(&t, &o.opts);
  t.push_back({"mcon", "N",
               "hold cameras 0..N-1 fixed (default 0); fixing the gauge this way lets a problem with\n"
               "fewer observations than parameters be solved",
               [&o](const std::string &v) { return sbacli::to_int(v, 0, kIntMax, &o.mcon); }});
  t.push_back({"ncon", "N", "hold points 0..N-1 fixed (default 0)",
               [&o](const std::string &v) { return sbacli::to_int(v, 0, kIntMax, &o.ncon); }});
  t.push_back({"verbose", "N", "library verbosity (default 0)",
               [&o](const std::string &v) { return sbacli::to_int(v, 0, kIntMax, &o.verbose); }});
  t.push_back({"loss", "NAME", "robust loss: none (least squares, the default), huber, cauchy, soft-l1 or tukey",
               [&o](const std::string &v) { return sbacli::to_loss(v, &o.loss); }});
  t.push_back({"loss-scale", "S", "scale of the robust loss, in pixels (default 1)",
               [&o](const std::string &v) { return sbacli::to_real(v, 0.0, true, &o.loss_scale); }});
  t.push_back({"write", "OUT", "write the refined problem in BAL format (OUT ending in .bz2: compressed)",
               [&o](const std::string &v) { return sbacli::to_file(v, &o.write); }});
  t.push_back({"max-time", "SECONDS",
               "stop after the iteration that ends past SECONDS; the results are then the last\n"
               "accepted estimate. SIGINT (Ctrl-C) or SIGTERM stop the same way, with exit status 130\n"
               "or 143; a second one ends the program at once",
               [&o](const std::string &v) { return sbacli::to_seconds(v, &o.max_time); }});
  t.push_back({"json", "FILE",
               "write the run as one JSON object: sizes, options, every info[] value, the error and\n"
               "time of every iteration, and each camera's observations and RMS reprojection error",
               [&o](const std::string &v) { return sbacli::to_file(v, &o.json); }});
  t.push_back({"no-progress", "", "no progress line (shown on stderr when it is a terminal)",
               [&o](const std::string &) -> std::string {
                 o.progress = false;
                 return {};
               }});
  return t;
}

bool parse_command_line(int argc, char **argv, Options *options, std::string *error) {
  Options o;
  sbacli::Parsed parsed;
  if (!sbacli::parse(argc, argv, option_table(o), &parsed, error)) return false;
  o.help = parsed.help;
  o.version = parsed.version;
  if (!o.help && !o.version && parsed.positional.size() != 1) {
    *error = "expected 1 file argument (a BAL problem), got " + std::to_string(parsed.positional.size()) +
             " (see --help)";
    return false;
  }
  if (!parsed.positional.empty()) o.file = parsed.positional[0];
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

// The library's messages: progress (--verbose) to stdout, warnings to stderr, and the first
// error kept for balsba's own one-line failure message.
struct LogSink {
  std::string first_error;
};

void log_line(void *ctx, int level, const char *line) {
  LogSink *sink = static_cast<LogSink *>(ctx);
  if (level == SBA_LOG_ERROR) {
    if (sink->first_error.empty()) sink->first_error = line;
    return;
  }
  std::fprintf(level == SBA_LOG_INFO ? stdout : stderr, "%s\n", line);
}

int bal_main(int argc, char **argv) {
  Options o;
  std::string error;
  if (!parse_command_line(argc, argv, &o, &error)) {
    std::fprintf(stderr, "balsba: %s\n", error.c_str());
    return kExitUsage;
  }
  if (o.help) {
    print_usage(stdout);
    return 0;
  }
  if (o.version) {
    std::printf("%s\n", sbacli::version_line("balsba").c_str());
    return 0;
  }
  // The output files must be writable before a long solve.
  for (const std::string *path : {&o.write, &o.json})
    if (!path->empty() && !sbademo::probe_writable(*path, &error)) {
      std::fprintf(stderr, "%s: %s\n", path->c_str(), error.c_str());
      return kExitFailure;
    }

  const auto read_start = std::chrono::steady_clock::now();
  bal::Problem problem;
  bal::SbaLayout s;
  if (!bal::read_problem(o.file, &problem, &error) || !bal::to_sba(problem, o.file, &s, &error)) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return kExitFailure;
  }
  const double read_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - read_start).count();
  if (o.mcon > s.m) {
    std::fprintf(stderr, "balsba: --mcon %d is more than the %d cameras\n", o.mcon, s.m);
    return kExitUsage;
  }
  if (o.ncon > s.n) {
    std::fprintf(stderr, "balsba: --ncon %d is more than the %d points\n", o.ncon, s.n);
    return kExitUsage;
  }

  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = o.solver.empty() ? nullptr : o.solver.c_str();
  ext.strategy = o.strategy.empty() ? nullptr : o.strategy.c_str();
  ext.nthreads = o.threads;
  // The BAL callbacks are re-entrant and walk the index by rows: let the threads share them.
  ext.parallel_callbacks = 1;
  LogSink sink;
  ext.log = log_line;
  ext.log_ctx = &sink;
  sba_ext_result result;
  sba_ext_result_init(&result);
  ext.result = &result;
  if (!o.loss.empty()) {
    ext.loss = o.loss.c_str();
    ext.loss_scale = o.loss_scale;
  }

  bal::CallbackData data;
  data.ncameras = s.m;
  std::array<double, SBA_INFOSZ> info{};
  const int nobs = s.nobservations();
  sbademo::TtyProgress progress(o.progress, nobs);
  sbademo::RunControl control(o.max_time, &progress);
  sbademo::RunControl::catch_signals();
  control.attach(&ext);
  const auto start = std::chrono::steady_clock::now();
  const int ret = sba_motstr_levmar_x_ext(s.n, o.ncon, s.m, o.mcon, s.vmask.data(), s.p.data(), bal::kCameraParams,
                                          bal::kPointParams, s.x.data(), nullptr, bal::kMeasurementParams,
                                          bal::motstr_func, bal::motstr_fjac, &data, o.itmax, o.verbose,
                                          o.opts.data(), info.data(), &ext);
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
  std::printf("\nSBA returned %d in %g iter, reason %g, error %g [initial %g], %d/%d func/fjac evals, "
              "%d lin. systems\n",
              ret, info[5], info[6], info[1] / nobs, info[0] / nobs, static_cast<int>(info[7]),
              static_cast<int>(info[8]), static_cast<int>(info[9]));
  std::printf("Elapsed time: %.2f seconds, %.2f msecs (reading the file: %.2f seconds)\n", seconds,
              seconds * 1000.0, read_seconds);
  if (result.robust)
    std::printf("Robust loss %s (scale %g): the errors above are its cost; squared error %g "
                "[initial %g], %lld observations beyond the scale\n",
                o.loss.c_str(), o.loss_scale, result.sq_error_final / nobs, result.sq_error_initial / nobs,
                result.outliers_final);

  sbademo::Report report;
  report.program = "balsba";
  report.inputs = {o.file};
  report.cameras = s.m;
  report.points = s.n;
  report.observations = nobs;
  report.variables = nvars;
  report.solver_requested = o.solver;
  report.strategy_requested = o.strategy;
  report.threads_requested = o.threads;
  report.itmax = o.itmax;
  report.opts = o.opts;
  report.loss = o.loss;
  report.loss_scale = o.loss_scale;
  report.mcon = o.mcon;
  report.ncon = o.ncon;
  report.max_time = o.max_time;
  report.ret = ret;
  report.info = info;
  report.result = result;
  report.seconds = seconds;
  report.iterations = control.iterations();
  sbademo::print_report(stdout, report);
  if (!o.json.empty()) {
    // Each camera's squared pixel distances at the result.
    report.per_camera.resize(static_cast<std::size_t>(s.m));
    const double *points = s.p.data() + static_cast<std::size_t>(s.m) * bal::kCameraParams;
    std::size_t k = 0;
    for (int i = 0; i < s.n; ++i)
      for (int j = 0; j < s.m; ++j) {
        if (!s.vmask[static_cast<std::size_t>(i) * s.m + j]) continue;
        double x[2];
        bal::project(s.p.data() + static_cast<std::size_t>(j) * bal::kCameraParams,
                     points + static_cast<std::size_t>(i) * bal::kPointParams, x);
        const double dx = x[0] - s.x[2 * k], dy = x[1] - s.x[2 * k + 1];
        report.per_camera[static_cast<std::size_t>(j)].observations += 1;
        report.per_camera[static_cast<std::size_t>(j)].sum_sq += dx * dx + dy * dy;
        ++k;
      }
    if (!sbademo::write_json(o.json, report, &error)) {
      std::fprintf(stderr, "%s: %s\n", o.json.c_str(), error.c_str());
      return kExitFailure;
    }
  }
  if (!o.write.empty()) std::printf("Wrote %s\n", o.write.c_str());
  // A stopped solve is a result (written above), but the status says it was cut short by a
  // signal; a time limit the user set is an ordinary end.
  if (info[6] == SBA_STOP_USER) {
    const int iterations = static_cast<int>(info[5]);
    if (control.stop_signal() != 0) {
      std::fprintf(stderr, "balsba: interrupted by %s after iteration %d: the results are the last accepted estimate\n",
                   control.stop_signal() == SIGINT ? "SIGINT" : "SIGTERM", iterations);
      return 128 + control.stop_signal();
    }
    std::fprintf(stderr, "balsba: --max-time %g s reached after iteration %d: the results are the last accepted estimate\n",
                 o.max_time, iterations);
  }
  return 0;
}

}  // namespace

int main(int argc, char **argv) {
  try {
    const int status = bal_main(argc, argv);
    // A report that did not reach stdout is a failed run, not a success.
    if (status == 0 && !sbademo::stdout_written("balsba")) return kExitFailure;
    return status;
  } catch (const std::bad_alloc &) {
    std::fprintf(stderr, "balsba: out of memory\n");
  } catch (const std::exception &e) {
    std::fprintf(stderr, "balsba: %s\n", e.what());
  } catch (...) {
    std::fprintf(stderr, "balsba: unexpected error\n");
  }
  return kExitFailure;
}
