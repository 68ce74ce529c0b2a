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
#include <new>
#include <string>
#include <vector>

#include "bal_io.h"
#include "bal_model.h"
#include "output_file.h"
#include "sba.h"
#include "sba_ext.h"
#include "tty_progress.h"

namespace {

constexpr int kExitFailure = 1;  // unreadable input, failed write, solver failure
constexpr int kExitUsage = 2;    // bad command line

const char kUsage[] =
    "usage: balsba FILE [options]\n"
    "Bundle-adjusts a BAL problem (\"Bundle Adjustment in the Large\": plain text or .bz2)\n"
    "with sba_motstr_levmar_x_ext: cameras (Rodrigues rotation, translation, f, k1, k2) and\n"
    "points, analytic Jacobian, no fixed cameras or points, default LM options.\n"
    "\n"
    "  --solver NAME   linear solver of the normal equations (default: $SBA_LINSOLVER, else chol)\n"
    "  --threads N     threads (default 0: $SBA_NUM_THREADS, else the hardware's, one per 10k projections at most)\n"
    "  --itmax N       most LM iterations (default 150)\n"
    "  --verbose N     sba's verbosity (default 0)\n"
    "  --write OUT     write the refined problem in BAL format (.bz2: compressed)\n"
    "  --loss NAME     robust loss: none (default), huber, cauchy, soft-l1, tukey\n"
    "  --loss-scale S  its scale in pixels (default 1)\n"
    "  --no-progress   no progress line (shown on stderr when it is a terminal)\n"
    "  --help          this text\n"
    "\n"
    "Prints the sizes, the initial and final mean squared reprojection error (pixels^2 per\n"
    "observation), iterations, stop reason, evaluations and the solve time.\n"
    "Exit status: 0 done, 1 a file cannot be read or written or the solver fails, 2 bad options.\n";

struct Options {
  std::string file;
  std::string solver;  // empty: the library's default
  int threads = 0;
  int itmax = 150;
  int verbose = 0;
  std::string write;
  std::string loss;  // empty: least squares
  double loss_scale = 1.0;
  bool progress = true;
  bool help = false;
};

bool parse_int(const std::string &text, int lo, int hi, int *out) {
  if (text.empty()) return false;
  errno = 0;
  char *end = nullptr;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (errno != 0 || *end != '\0' || v < lo || v > hi) return false;
  *out = static_cast<int>(v);
  return true;
}

bool parse_command_line(int argc, char **argv, Options *o, std::string *error) {
  for (int k = 1; k < argc; ++k) {
    const std::string arg = argv[k];
    if (arg == "--help" || arg == "-h") {
      o->help = true;
      return true;
    }
    if (arg == "--no-progress") {
      o->progress = false;
      continue;
    }
    if (arg.size() > 2 && arg.compare(0, 2, "--") == 0) {
      const std::string name = arg.substr(2);
      if (name != "solver" && name != "threads" && name != "itmax" && name != "verbose" && name != "write" &&
          name != "loss" && name != "loss-scale") {
        *error = "unknown option '" + arg + "' (see --help)";
        return false;
      }
      if (k + 1 >= argc) {
        *error = "option " + arg + " needs a value";
        return false;
      }
      const std::string value = argv[++k];
      bool ok = true;
      if (name == "solver") o->solver = value;
      else if (name == "threads") ok = parse_int(value, 0, 4096, &o->threads);
      else if (name == "itmax") ok = parse_int(value, 0, INT_MAX, &o->itmax);
      else if (name == "verbose") ok = parse_int(value, 0, 10, &o->verbose);
      else if (name == "loss") {
        ok = value == "none" || value == "huber" || value == "cauchy" || value == "soft-l1" || value == "tukey";
        o->loss = value == "none" ? std::string() : value;
      } else if (name == "loss-scale") {
        char *end = nullptr;
        o->loss_scale = std::strtod(value.c_str(), &end);
        ok = !value.empty() && *end == '\0' && std::isfinite(o->loss_scale) && o->loss_scale > 0;
      } else o->write = value;
      if (!ok) {
        *error = "bad value '" + value + "' for " + arg;
        return false;
      }
      continue;
    }
    if (!o->file.empty()) {
      *error = "more than one input file ('" + o->file + "' and '" + arg + "')";
      return false;
    }
    o->file = arg;
  }
  if (o->file.empty()) {
    *error = "no input file (usage: balsba FILE [options]; see --help)";
    return false;
  }
  return true;
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
    std::fputs(kUsage, stdout);
    return 0;
  }
  if (!o.solver.empty() && !sba_linsolver_valid(o.solver.c_str())) {
    std::fprintf(stderr, "balsba: unknown solver '%s' (known: %s)\n", o.solver.c_str(),
                 sba_linsolver_names());
    return kExitUsage;
  }
  // OUT must be writable before a long solve.
  if (!o.write.empty() && !sbademo::probe_writable(o.write, &error)) {
    std::fprintf(stderr, "%s: %s\n", o.write.c_str(), error.c_str());
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

  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = o.solver.empty() ? nullptr : o.solver.c_str();
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
  progress.attach(&ext);
  const auto start = std::chrono::steady_clock::now();
  const int ret = sba_motstr_levmar_x_ext(s.n, 0, s.m, 0, s.vmask.data(), s.p.data(), bal::kCameraParams,
                                          bal::kPointParams, s.x.data(), nullptr, bal::kMeasurementParams,
                                          bal::motstr_func, bal::motstr_fjac, &data, o.itmax, o.verbose,
                                          nullptr, info.data(), &ext);
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
  std::printf("Solver %s, %s threads\n", o.solver.empty() ? "default" : o.solver.c_str(),
              o.threads > 0 ? std::to_string(o.threads).c_str() : "default");
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
  if (!o.write.empty()) std::printf("Wrote %s\n", o.write.c_str());
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
