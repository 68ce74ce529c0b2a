/* SPDX-License-Identifier: BSD-3-Clause */
// What balsba and sbarefine share around their motion-and-structure solve: the options and
// their --help rows, the library's log sink, the printed summary and the JSON report.
#ifndef SBA_DEMO_SOLVE_OPTIONS_H
#define SBA_DEMO_SOLVE_OPTIONS_H

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <initializer_list>
#include <new>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include "cli/cli.h"
#include "cli/report.h"
#include "cli/run_control.h"
#include "formats/output_file.h"
#include "formats/visibility.h"
#include "sba_ext.h"

namespace sbacli {

struct SolveOptions {
  std::string solver;    // empty: SBA_LINSOLVER if set, else auto (linsolver_of)
  std::string strategy;  // empty: the library's default (SBA_STRATEGY, else sba)
  int threads = 0;
  int itmax = 150;
  std::array<double, 5> opts{1e-3, 1e-12, 1e-12, 1e-12, 0.0};  // sba 1.6's defaults
  int verbose = 0;
  int mcon = 0, ncon = 0;
  std::string loss;  // empty: least squares
  double loss_scale = 1.0;
  bool progress = true;
  double max_time = 0;  // 0: no limit
  std::string json;     // the run as one JSON object; empty: not written
};

// What a program's --help says of a default that is its own, not the library's or 150
// iterations (null: that one).
struct SolveDefaults {
  const char *strategy = nullptr;  // after "default: " (strategy_option)
  const char *itmax = nullptr;     // in the parentheses after "maximum iterations"
};

// The rows of the options above, in --help order; `write` (the program's own output option)
// goes after --loss-scale.
inline void add_solve_options(std::vector<Option> *t, SolveOptions &o, const Option &write,
                              const SolveDefaults &defaults = {}) {
  const int kIntMax = std::numeric_limits<int>::max();
  t->push_back({"solver", "NAME",
                "linear solver of the normal equations, one of those listed below (default:\n"
                "the environment variable SBA_LINSOLVER if set, else auto: chol, sparse-chol or\n"
                "iterative-schur, chosen from the problem's size, its sparsity and the memory)",
                [&o](const std::string &v) { return to_linsolver(v, &o.solver); }});
  t->push_back(strategy_option(&o.strategy, defaults.strategy));
  t->push_back({"threads", "N",
                "threads; 0 (the default): SBA_NUM_THREADS if set, else every hardware thread, but at\n"
                "most one per 10,000 observations. The result does not depend on it. A worker that\n"
                "finds itself on the core of another of them moves to a free core\n"
                "(SBA_AVOID_SHARED_CORES=0: left to the scheduler)",
                [&o](const std::string &v) { return to_threads(v, &o.threads); }});
  t->push_back({"itmax", "N",
                std::string("maximum iterations (") + (defaults.itmax ? defaults.itmax : "default 150") + ")",
                [&o](const std::string &v) { return to_int(v, 0, kIntMax, &o.itmax); }});
  add_lm_options(t, &o.opts);
  t->push_back({"mcon", "N",
                "hold cameras 0..N-1 fixed (default 0); fixing the gauge this way lets a problem with\n"
                "fewer observations than parameters be solved",
                [&o](const std::string &v) { return to_int(v, 0, kIntMax, &o.mcon); }});
  t->push_back({"ncon", "N", "hold points 0..N-1 fixed (default 0)",
                [&o](const std::string &v) { return to_int(v, 0, kIntMax, &o.ncon); }});
  t->push_back({"verbose", "N", "library verbosity (default 0)",
                [&o](const std::string &v) { return to_int(v, 0, kIntMax, &o.verbose); }});
  t->push_back({"loss", "NAME", "robust loss: none (least squares, the default), huber, cauchy, soft-l1 or tukey",
                [&o](const std::string &v) { return to_loss(v, &o.loss); }});
  t->push_back({"loss-scale", "S", "scale of the robust loss, in pixels (default 1)",
                [&o](const std::string &v) { return to_real(v, 0.0, true, &o.loss_scale); }});
  t->push_back(write);
  t->push_back({"max-time", "SECONDS",
                "stop after the iteration that ends past SECONDS; the results are then the last\n"
                "accepted estimate. SIGINT (Ctrl-C) or SIGTERM stop the same way, with exit status 130\n"
                "or 143; a second one ends the program at once",
                [&o](const std::string &v) { return to_seconds(v, &o.max_time); }});
  t->push_back({"json", "FILE",
                "write the run as one JSON object: sizes, options, every info[] value, the error and\n"
                "time of every iteration, and each camera's observations and RMS reprojection error",
                [&o](const std::string &v) { return to_file(v, &o.json); }});
  t->push_back({"no-progress", "", "no progress line (shown on stderr when it is a terminal)",
                [&o](const std::string &) -> std::string {
                  o.progress = false;
                  return {};
                }});
}

// Parses argv against the table of a program that takes one input (described by `what` in
// the message when it is missing or repeated), unless --help or --version is asked for.
inline bool parse_one_input(int argc, char **argv, const std::vector<Option> &table, const char *what,
                            std::string *input, bool *help, bool *version, std::string *error) {
  Parsed parsed;
  if (!parse(argc, argv, table, &parsed, error)) return false;
  *help = parsed.help;
  *version = parsed.version;
  if (!parsed.help && !parsed.version && parsed.positional.size() != 1) {
    *error = std::string("expected 1 ") + what + ", got " + std::to_string(parsed.positional.size()) + " (see --help)";
    return false;
  }
  if (!parsed.positional.empty()) *input = parsed.positional[0];
  return true;
}

// What main() does with the parsed command line before any work: a bad one is reported
// ("PROGRAM: error", exit 2), --help and --version are answered (exit 0). Returns the exit
// status when the program ends there, -1 when it goes on.
inline int answer_command_line(const char *program, bool parsed, const std::string &error, bool help, bool version,
                               void (*usage)(std::FILE *)) {
  if (!parsed) {
    std::fprintf(stderr, "%s: %s\n", program, error.c_str());
    return kExitUsage;
  }
  if (help) {
    usage(stdout);
    return 0;
  }
  if (version) {
    std::printf("%s\n", version_line(program).c_str());
    return 0;
  }
  return -1;
}

// The output files must be writable before a long solve: false, with "PATH: why" printed,
// for the first that is not (empty paths are not asked for).
inline bool outputs_writable(std::initializer_list<const std::string *> paths) {
  std::string why;
  for (const std::string *path : paths)
    if (!path->empty() && !sbaformats::probe_writable(*path, &why)) {
      std::fprintf(stderr, "%s: %s\n", path->c_str(), why.c_str());
      return false;
    }
  return true;
}

// The library's messages: progress (--verbose) to stdout, warnings to stderr, and the first
// error kept for the program's own one-line failure message.
struct LogSink {
  std::string first_error;
};

inline void log_line(void *ctx, int level, const char *line) {
  LogSink *sink = static_cast<LogSink *>(ctx);
  if (level == SBA_LOG_ERROR) {
    if (sink->first_error.empty()) sink->first_error = line;
    return;
  }
  std::fprintf(level == SBA_LOG_INFO ? stdout : stderr, "%s\n", line);
}

// The linear solver a program asks the library for: `given` (--solver) if not empty, else
// SBA_LINSOLVER when set (a name the library does not know is said, and `fallback` used), else
// `fallback`, the program's default: auto for balsba and sbarefine, sba 1.6's chol for
// eucsbademo. Named in full, so that the report can say what was asked.
inline const char *linsolver_of(const std::string &given, const char *program, const char *fallback) {
  if (!given.empty()) return given.c_str();
  const char *env = std::getenv("SBA_LINSOLVER");
  if (!env || !*env) return fallback;
  if (sba_linsolver_valid(env)) return env;
  std::fprintf(stderr, "%s: unknown SBA_LINSOLVER \"%s\" (known: %s); using %s\n", program, env,
               sba_linsolver_names(), fallback);
  return fallback;
}

// The programs own their processes, so they make the choice the library leaves to its host
// (docs/threads.md): a worker that finds itself on the core of another of the solve's threads
// moves to a core none of them uses. A new thread starts on its creator's core, and on a
// virtual machine the kernel can keep the two there for much of a short solve. Where
// SBA_AVOID_SHARED_CORES is set, it decides, as in any host: off unless it is 1 (the library
// reads it too, and says what is wrong with another value).
inline bool avoids_shared_cores() {
  const char *env = std::getenv("SBA_AVOID_SHARED_CORES");
  return !env || std::string(env) == "1";
}

// The extension options of a solve: solver, strategy, threads, loss, the log sink and the
// result record. The callbacks must be re-entrant (they are shared by the threads).
inline void init_ext(const SolveOptions &o, const char *program, LogSink *sink, sba_ext_result *result,
                     sba_ext_options *ext) {
  sba_ext_options_init(ext);
  ext->linsolver = linsolver_of(o.solver, program, "auto");
  ext->strategy = o.strategy.empty() ? nullptr : o.strategy.c_str();
  ext->nthreads = o.threads;
  ext->avoid_shared_cores = avoids_shared_cores();
  ext->parallel_callbacks = 1;
  ext->log = log_line;
  ext->log_ctx = sink;
  sba_ext_result_init(result);
  ext->result = result;
  if (!o.loss.empty()) {
    ext->loss = o.loss.c_str();
    ext->loss_scale = o.loss_scale;
  }
}

// The report's options part.
inline void report_options(const SolveOptions &o, Report *r) {
  r->solver_requested = o.solver;
  r->strategy_requested = o.strategy;
  r->threads_requested = o.threads;
  r->avoid_shared_cores = avoids_shared_cores();
  r->itmax = o.itmax;
  r->opts = o.opts;
  r->loss = o.loss;
  r->loss_scale = o.loss_scale;
  r->mcon = o.mcon;
  r->ncon = o.ncon;
  r->max_time = o.max_time;
}

// The message and exit status of a solve that ended on SBA_STOP_USER: 128 + the signal that
// stopped it, or 0 when the time limit did.
inline int stopped_status(const char *program, const RunControl &control, double max_time, int iterations) {
  if (control.stop_signal() != 0) {
    std::fprintf(stderr, "%s: interrupted by %s after iteration %d: the results are the last accepted estimate\n",
                 program, control.stop_signal_name(), iterations);
    return 128 + control.stop_signal();
  }
  std::fprintf(stderr, "%s: --max-time %g s reached after iteration %d: the results are the last accepted estimate\n",
               program, max_time, iterations);
  return 0;
}

// What a solve prints after its sizes line: sba 1.6's summary, the time, the robust loss.
inline void print_summary(int nobs, int ret, const std::array<double, SBA_INFOSZ> &info, double seconds,
                          double read_seconds, const sba_ext_result &result, const SolveOptions &o) {
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
}

// The report of a motion-and-structure solve.
inline Report make_report(const char *program, const std::string &input, int m, int n, int nobs, long long nvars,
                          const SolveOptions &o, int ret, const std::array<double, SBA_INFOSZ> &info,
                          const sba_ext_result &result, double seconds, const RunControl &control) {
  Report r;
  r.program = program;
  r.inputs = {input};
  r.cameras = m;
  r.points = n;
  r.observations = nobs;
  r.variables = nvars;
  report_options(o, &r);
  r.ret = ret;
  r.info = info;
  r.result = result;
  r.seconds = seconds;
  r.iterations = control.iterations();
  return r;
}

// xp = the projection of point i in camera j through project(j, i, xp), or the measurement
// x_k (2 values) where project returns false: a projection the camera model refuses (a point
// behind a COLMAP camera), which the solve costs nothing.
template <class Project>
void projection_or_measurement(Project &project, int j, int i, const double *x_k, double xp[2]) {
  if constexpr (std::is_same_v<decltype(project(j, i, xp)), bool>) {
    if (project(j, i, xp)) return;
    xp[0] = x_k[0];
    xp[1] = x_k[1];
  } else {
    project(j, i, xp);
  }
}

// Each camera's squared pixel distances at the result, for --json: project(j, i, x) gives
// the projection of point i in camera j (projection_or_measurement); x holds measurement k of
// vis at x[2k], x[2k + 1].
template <class Project>
void add_per_camera(int m, const sbaformats::Visibility &vis, const double *x, Project project, Report *r) {
  r->per_camera.assign(static_cast<std::size_t>(m), {});
  for (std::size_t k = 0; k < vis.size(); ++k) {
    const int j = vis.camera[k];
    double xp[2];
    projection_or_measurement(project, j, vis.point[k], x + 2 * k, xp);
    const double dx = xp[0] - x[2 * k], dy = xp[1] - x[2 * k + 1];
    r->per_camera[static_cast<std::size_t>(j)].observations += 1;
    r->per_camera[static_cast<std::size_t>(j)].sum_sq += dx * dx + dy * dy;
  }
}

// COLMAP's mean reprojection error (Reconstruction::ComputeMeanReprojectionError, what its
// model_analyzer and pycolmap report): each point's mean pixel distance over its observations
// (the ERROR of a refined point that sbarefine writes), averaged over the points. project as
// add_per_camera's; vis lists each point's observations together. NaN for no observation.
template <class Project>
double mean_error_by_point(const sbaformats::Visibility &vis, const double *x, Project project) {
  double total = 0;
  long long points = 0;
  for (std::size_t k = 0; k < vis.size(); ++points) {
    const int i = vis.point[k];
    double sum = 0;
    long long count = 0;
    for (; k < vis.size() && vis.point[k] == i; ++k, ++count) {
      double xp[2];
      projection_or_measurement(project, vis.camera[k], i, x + 2 * k, xp);
      sum += std::hypot(xp[0] - x[2 * k], xp[1] - x[2 * k + 1]);
    }
    total += sum / static_cast<double>(count);
  }
  return points > 0 ? total / static_cast<double>(points) : NAN;
}

// main() of a program: its exit status, 1 when the report did not reach stdout or an
// exception escaped (out of memory above all), with one line saying so.
template <class Main>
int guarded_main(const char *program, Main run, int argc, char **argv) {
  int status = kExitFailure;
  try {
    status = run(argc, argv);
  } catch (const std::bad_alloc &) {
    std::fprintf(stderr, "%s: out of memory\n", program);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "%s: %s\n", program, e.what());
  } catch (...) {
    std::fprintf(stderr, "%s: unexpected error\n", program);
  }
  RunControl::release_signals();
  // A report that did not reach stdout is a failed run, not a success.
  if (status == 0 && !sbaformats::stdout_written(program)) return kExitFailure;
  return status;
}

}  // namespace sbacli

#endif  // SBA_DEMO_SOLVE_OPTIONS_H
