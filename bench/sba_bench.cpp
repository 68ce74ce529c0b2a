// SPDX-License-Identifier: BSD-3-Clause
// sba_bench: one problem, solved from the same starting point by this library (each linear
// solver and LM strategy asked for, at each thread count) and by Ceres Solver as its users run
// it (its default Solver::Options but for the linear solver: DENSE_SCHUR, SPARSE_SCHUR or
// ITERATIVE_SCHUR with SCHUR_JACOBI; same camera model, same analytic Jacobian, same
// parameters), each run in a fresh child process so that its peak RSS is its own.
//
// Reported per run: the wall time of the solve (problem loading excluded; for Ceres the
// construction of the ceres::Problem is included, as sba builds its own structures inside
// the call), iterations, time per iteration, initial and final mean squared reprojection
// error (sum of squared residuals / observations, sba's scale), peak RSS, the ratio to the
// fastest Ceres configuration with the same thread count (and whether the run ended at a
// worse error than that Ceres run, beyond 1e-6 relative: then it is no win whatever its
// time), and the time at which the run's error first came within (1 + 1e-6) of the best
// final error over all runs ("time to best").
#include <dirent.h>
#include <dlfcn.h>
#include <fcntl.h>
#include <malloc.h>
#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <sys/time.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <exception>
#include <memory>
#include <new>
#include <string>
#include <thread>
#include <vector>

#include <ceres/ceres.h>

#include "bench_problem.h"
#include "ceres_models.h"
#include "cli.h"
#include "sba.h"
#include "sba_ext.h"

namespace sbabench {
namespace {

constexpr double kBestTolerance = 1e-6;  // "within 1e-6 relative of the best final error"

const char kUsage[] =
    "Usage: sba_bench PROBLEM [OPTION]...\n"
    "Solves one bundle adjustment problem with sba (each --solvers name with each --strategy\n"
    "at each --threads count) and with Ceres at its default options (LM; DENSE_SCHUR,\n"
    "SPARSE_SCHUR or ITERATIVE_SCHUR + SCHUR_JACOBI), each run in a child process.\n"
    "\n"
    "PROBLEM, one of:\n"
    "  --cams FILE --pts FILE [--calib FILE]   eucsbademo files (calib: fixed K)\n"
    "  --bal FILE                              a BAL file (.txt or .bz2)\n"
    "  --gen SPEC                              a sbagen scene, SPEC = key=value,... with keys\n"
    "                                          cameras, points, track (MIN..MAX), trajectory\n"
    "                                          (orbit|path|photo), kind (fixed|varK|varKD), noise, seed\n"
    "\n"
    "Options (a value may follow as --opt=VALUE or --opt VALUE; '--' ends the options):\n";

// ---- options ----

struct Options {
  std::string cams, pts, calib, bal, gen, name;
  std::vector<std::string> solvers{"chol"};
  std::vector<std::string> strategies{"sba"};
  std::vector<std::string> ceres{"dense", "sparse"};
  bool ceres_tight = false;  // --ceres-tight
  std::vector<int> threads;
  std::vector<char> threads_auto;  // per entry of threads: given as "all"
  int itmax = 150;
  int repeat = 1;
  double timeout = 3600;
  std::string out;
  bool fork = true;
  bool warm_up = false;
  bool blas_same = true;  // --blas-threads same
  bool avoid_shared_cores = false;  // --avoid-shared-cores
  bool help = false, version = false;
};

std::vector<std::string> split(const std::string &s) {
  std::vector<std::string> items;
  std::size_t start = 0;
  while (start <= s.size()) {
    std::size_t comma = s.find(',', start);
    if (comma == std::string::npos) comma = s.size();
    if (comma > start) items.push_back(s.substr(start, comma - start));
    start = comma + 1;
  }
  return items;
}

int hardware_threads() { return std::max(1, static_cast<int>(std::thread::hardware_concurrency())); }

std::vector<sbacli::Option> option_table(Options &o, std::string *threads) {
  auto text = [](std::string *field) {
    return [field](const std::string &v) { return sbacli::to_file(v, field); };
  };
  auto flag = [](bool *field) {
    return [field](const std::string &) -> std::string {
      *field = true;
      return {};
    };
  };
  std::vector<sbacli::Option> t;
  t.push_back({"cams", "FILE", "eucsbademo camera file", text(&o.cams)});
  t.push_back({"pts", "FILE", "eucsbademo points file", text(&o.pts)});
  t.push_back({"calib", "FILE", "eucsbademo calibration file (fixed K)", text(&o.calib)});
  t.push_back({"bal", "FILE", "a BAL problem (.txt or .bz2)", text(&o.bal)});
  t.push_back({"gen", "SPEC", "a sbagen scene (see above)", text(&o.gen)});
  t.push_back({"name", "LABEL", "problem name in the output (default: from the files / the spec)", text(&o.name)});
  t.push_back({"solvers", "LIST", "sba linear solvers, comma-separated, or none (default chol)",
               [&o](const std::string &v) -> std::string {
                 std::vector<std::string> names;
                 for (const std::string &item : v == "none" ? std::vector<std::string>{} : split(v)) {
                   std::string name;
                   if (std::string why = sbacli::to_linsolver(item, &name); !why.empty())
                     return "'" + item + "': " + why;
                   names.push_back(name);
                 }
                 o.solvers = names;
                 return {};
               }});
  t.push_back({"strategy", "LIST",
               "sba LM strategies, comma-separated (default sba; the library's names:\n"
               "sba_strategy_names())",
               [&o](const std::string &v) -> std::string {
                 std::vector<std::string> names;
                 for (const std::string &item : split(v)) {
                   std::string name;
                   if (std::string why = sbacli::to_strategy(item, &name); !why.empty())
                     return "'" + item + "': " + why;
                   names.push_back(name);
                 }
                 if (names.empty()) return "expected strategy names, comma-separated";
                 o.strategies = names;
                 return {};
               }});
  t.push_back({"ceres", "LIST",
               "Ceres linear solvers, comma-separated: dense (DENSE_SCHUR), sparse (SPARSE_SCHUR),\n"
               "iterative (ITERATIVE_SCHUR with SCHUR_JACOBI), or none (default dense,sparse); Ceres\n"
               "runs with its default Solver::Options otherwise",
               [&o](const std::string &v) -> std::string {
                 std::vector<std::string> names;
                 for (const std::string &item : v == "none" ? std::vector<std::string>{} : split(v)) {
                   std::string name;
                   if (std::string why = sbacli::to_choice(item, {"dense", "sparse", "iterative"}, &name); !why.empty())
                     return "'" + item + "': " + why;
                   names.push_back(name);
                 }
                 o.ceres = names;
                 return {};
               }});
  t.push_back({"ceres-tight", "",
               "Ceres with function, gradient and parameter tolerances of 1e-12 instead of its\n"
               "defaults (a secondary comparison: Ceres then runs to the end)",
               flag(&o.ceres_tight)});
  t.push_back({"threads", "LIST",
               "thread counts, comma-separated (default 1,all); all = every hardware thread for Ceres,\n"
               "and for sba its default (nthreads 0: as many as the problem's size warrants, up to\n"
               "every hardware thread)",
               [threads](const std::string &v) -> std::string {
                 if (split(v).empty()) return "expected thread counts or all, comma-separated";
                 for (const std::string &item : split(v)) {
                   int n = 0;
                   if (item == "all") continue;
                   if (std::string why = sbacli::to_int(item, 1, sbacli::kMaxThreads, &n); !why.empty())
                     return "'" + item + "': " + why;
                 }
                 *threads = v;
                 return {};
               }});
  t.push_back({"itmax", "N", "iterations of every solver (default 150)",
               [&o](const std::string &v) { return sbacli::to_int(v, 0, INT_MAX, &o.itmax); }});
  t.push_back({"timeout", "SEC", "a run taking longer is killed and reported as such (default 3600)",
               [&o](const std::string &v) { return sbacli::to_seconds(v, &o.timeout); }});
  t.push_back({"repeat", "N",
               "run every configuration N times, in rounds, and report the run with the median time\n"
               "(default 1; all times go to the JSON)",
               [&o](const std::string &v) { return sbacli::to_int(v, 1, 100, &o.repeat); }});
  t.push_back({"out", "FILE", "append one JSON object per run to FILE (JSON lines)", text(&o.out)});
  t.push_back({"blas-threads", "W",
               "same (default): the BLAS runs as many threads as the run it serves; default: leave the\n"
               "BLAS alone (OpenBLAS: OPENBLAS_NUM_THREADS or every core, even in a 1-thread run)",
               [&o](const std::string &v) -> std::string {
                 std::string which;
                 if (std::string why = sbacli::to_choice(v, {"same", "default"}, &which); !why.empty()) return why;
                 o.blas_same = which == "same";
                 return {};
               }});
  t.push_back({"avoid-shared-cores", "",
               "sba runs with sba_ext_options.avoid_shared_cores on (workers that find themselves on\n"
               "another pool thread's core move off it); default off, as the library runs unless a\n"
               "program asks, unless SBA_AVOID_SHARED_CORES=1 is in the environment (the header says\n"
               "which)",
               flag(&o.avoid_shared_cores)});
  t.push_back({"no-fork", "", "run in this process (peak RSS then is the process's)",
               [&o](const std::string &) -> std::string {
                 o.fork = false;
                 return {};
               }});
  t.push_back({"warm-up", "",
               "before each measured solve, one iteration of the same run, its memory then returned:\n"
               "the code the solve runs is resident before the peak is reset, so that little of the\n"
               "peak is code new to the solve",
               flag(&o.warm_up)});
  return t;
}

void print_usage(std::FILE *out) {
  std::fputs(kUsage, out);
  Options scratch;
  std::string threads;
  sbacli::print_options(out, option_table(scratch, &threads));
}

bool parse_command_line(int argc, char **argv, Options *options, std::string *error) {
  Options o;
  std::string threads = "1,all";
  sbacli::Parsed parsed;
  if (!sbacli::parse(argc, argv, option_table(o, &threads), &parsed, error)) return false;
  o.help = parsed.help;
  o.version = parsed.version;
  if (o.help || o.version) {
    *options = std::move(o);
    return true;
  }
  if (!parsed.positional.empty()) {
    *error = "unexpected argument '" + parsed.positional[0] + "' (see --help)";
    return false;
  }
  const int sources = !o.cams.empty() + !o.bal.empty() + !o.gen.empty();
  if (sources != 1 || o.cams.empty() != o.pts.empty()) {
    *error = "give exactly one problem: --cams/--pts[/--calib], --bal or --gen (see --help)";
    return false;
  }
  for (const std::string &t : split(threads)) {
    const bool all = t == "all";
    const int n = all ? hardware_threads() : std::atoi(t.c_str());  // checked by the option
    bool seen = false;
    for (std::size_t k = 0; k < o.threads.size(); ++k)
      seen = seen || (o.threads[k] == n && (o.threads_auto[k] != 0) == all);
    if (!seen) {
      o.threads.push_back(n);
      o.threads_auto.push_back(all);
    }
  }
  *options = std::move(o);
  return true;
}

// ---- one run ----

enum class Engine { Sba, Ceres };

struct RunSpec {
  Engine engine;
  std::string solver;  // sba linsolver name, or "DENSE_SCHUR" / "SPARSE_SCHUR" / "ITERATIVE_SCHUR"
  int threads;       // Ceres's threads; sba's unless auto_threads
  bool auto_threads;  // sba: nthreads 0, the library's choice of at most `threads`
  int blas_threads;  // 0: as the BLAS decides
  bool avoid_shared_cores = false;  // sba: what the library runs with (flag or environment)
  std::string strategy = "sba";     // sba: the LM strategy
  bool ceres_tight = false;         // Ceres: tolerances 1e-12 instead of its defaults
  std::string label() const {
    if (engine == Engine::Ceres) return "ceres " + solver + (ceres_tight ? " tight" : "");
    return "sba " + solver + (strategy == "sba" ? "" : " " + strategy);
  }
};

// What a child sends back: plain data, then ntrace (seconds, ||e||^2) pairs.
struct RunResult {
  int ok = 0;             // 1: the solver returned a result
  char status[64] = {};   // stop reason in a few words
  char message[256] = {};  // Ceres's summary message
  double reason = 0;      // sba info[6]; Ceres: termination type
  int iterations = 0;     // sba: outer iterations (info[5]); Ceres: LM steps tried
  int linear_solves = 0;  // sba info[9]; Ceres: successful + unsuccessful steps
  int threads_used = 0;   // sba: sba_ext_result.nthreads; Ceres: the threads asked
  int func_evals = 0, jac_evals = 0;
  double seconds = 0;        // wall time of the solve
  double setup_seconds = 0;  // Ceres: building the ceres::Problem (part of seconds)
  double cpu_seconds = 0;    // CPU time of the whole process during the solve (all threads)
  double init_err = 0, final_err = 0;  // sum of squared residuals
  long long peak_rss = 0;    // bytes: VmHWM after resetting it just before the solve
  long long base_rss = 0;    // bytes: VmRSS just before the solve (program + inputs)
  long long file_rss_start = 0, file_rss_end = 0;  // bytes: RssFile + RssShmem around the solve
  int hwm_reset = 0;         // 1 if the reset worked (else peak includes the loading)
  int ntrace = 0;
};

struct Run {
  RunSpec spec;
  RunResult r;
  std::vector<std::array<double, 2>> trace;  // (seconds since the solve started, ||e||^2)
  long long child_maxrss = 0;                // ru_maxrss of the child, bytes (cross-check)
  std::vector<double> all_seconds;           // every repetition's time (--repeat), in run order
  double ttb = NAN;                          // time to best, seconds (NaN: never)
};

long long status_kb(const char *field) {
  std::FILE *f = std::fopen("/proc/self/status", "r");
  if (!f) return -1;
  char line[256];
  long long kb = -1;
  const std::size_t len = std::strlen(field);
  while (std::fgets(line, sizeof line, f))
    if (std::strncmp(line, field, len) == 0 && line[len] == ':') {
      kb = std::atoll(line + len + 1);
      break;
    }
  std::fclose(f);
  return kb;
}

// Resident pages backed by files: the code of the program and its libraries, which every
// process running them shares. Their count when a solve starts is a lower bound of their
// share of its peak (they are only added during a solve, nothing is unmapped); --warm-up
// makes it exact up to the code that only the measured solve runs.
long long file_rss() {
  const long long f = status_kb("RssFile"), s = status_kb("RssShmem");
  return f < 0 || s < 0 ? -1 : (f + s) * 1024;
}

// User + system time of every thread of this process so far.
double process_cpu_seconds() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  const auto sec = [](const timeval &t) { return double(t.tv_sec) + 1e-6 * double(t.tv_usec); };
  return sec(ru.ru_utime) + sec(ru.ru_stime);
}

bool reset_peak_rss() {
  const int fd = ::open("/proc/self/clear_refs", O_WRONLY);
  if (fd < 0) return false;
  const bool ok = ::write(fd, "5", 1) == 1;
  ::close(fd);
  return ok;
}

void set_status(RunResult *r, const std::string &s) {
  std::snprintf(r->status, sizeof r->status, "%s", s.c_str());
}

// ---- sba ----

struct SbaTrace {
  std::vector<std::array<double, 2>> *trace;
};

// Keeps the library's first error line (why a call returned SBA_ERROR) for the report.
void record_log(void *ctx, int level, const char *line) {
  RunResult *r = static_cast<RunResult *>(ctx);
  if (level == SBA_LOG_ERROR && r->message[0] == '\0') std::snprintf(r->message, sizeof r->message, "%s", line);
}

int record_progress(void *ctx, const sba_progress *state) {
  static_cast<SbaTrace *>(ctx)->trace->push_back({state->elapsed, state->error});
  return 0;
}

const char *sba_reason(double reason) {
  switch (static_cast<int>(reason)) {
    case 1: return "small gradient";
    case 2: return "small dp";
    case 3: return "itmax";
    case 4: return "small error reduction";
    case 5: return "small error";
    case 6: return "too many failed attempts";
    case 7: return "NaN or Inf";
    case SBA_STOP_SINGULAR: return "singular";
    case SBA_STOP_USER: return "stopped";
    default: return "error";
  }
}

// The parameters a run refines: the problem's own in a child (which has no further use for
// them, and a copy would count against the run's memory), a copy otherwise.
std::vector<double> initial_params(Problem &prob, bool consume) {
  return consume ? std::move(prob.p0) : prob.p0;
}

void run_sba(Problem &prob, const RunSpec &spec, int itmax, bool consume, RunResult *r,
             std::vector<std::array<double, 2>> *trace) {
  std::vector<double> p = initial_params(prob, consume);
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = spec.solver.c_str();
  ext.strategy = spec.strategy.c_str();
  ext.nthreads = spec.auto_threads ? 0 : spec.threads;
  sba_ext_result res;
  sba_ext_result_init(&res);
  ext.result = &res;
  // The demo and BAL models' callbacks are re-entrant and walk the index by rows.
  ext.parallel_callbacks = 1;
  ext.avoid_shared_cores = spec.avoid_shared_cores ? 1 : 0;
  ext.log = record_log;  // errors kept, nothing printed (verbose 0: no progress lines)
  ext.log_ctx = r;
  SbaTrace ctx{trace};
  trace->reserve(static_cast<std::size_t>(itmax) + 2);
  trace->push_back({0.0, NAN});  // the initial error, filled in below
  ext.progress = record_progress;
  ext.progress_ctx = &ctx;
  std::array<double, SBA_INFOSZ> info{};
  r->hwm_reset = reset_peak_rss();
  r->base_rss = status_kb("VmRSS") * 1024;
  r->file_rss_start = file_rss();
  const double cpu0 = process_cpu_seconds();
  const auto t0 = std::chrono::steady_clock::now();
  // The visibility as (point, camera) pairs: no n*m vmask needed (see Problem::vmask).
  const sba_visibility vis{static_cast<long long>(prob.obs_point.size()), prob.obs_point.data(),
                           prob.obs_camera.data()};
  const int ret = sba_motstr_levmar_x_vis(prob.n, 0, prob.m, 0, &vis, p.data(), prob.cnp, Problem::pnp,
                                          prob.x.data(), nullptr, Problem::mnp, prob.func(), prob.fjac(),
                                          prob.adata(), itmax, 0, nullptr, info.data(), &ext);
  r->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r->cpu_seconds = process_cpu_seconds() - cpu0;
  r->peak_rss = status_kb("VmHWM") * 1024;
  r->file_rss_end = file_rss();
  (*trace)[0][1] = info[0];
  r->ok = ret != SBA_ERROR;
  r->reason = info[6];
  r->iterations = static_cast<int>(info[5]);
  r->linear_solves = static_cast<int>(info[9]);
  r->threads_used = res.nthreads;
  r->func_evals = static_cast<int>(info[7]);
  r->jac_evals = static_cast<int>(info[8]);
  r->init_err = info[0];
  r->final_err = info[1];
  if (ret == SBA_ERROR && info[6] == SBA_STOP_NONE) set_status(r, "SBA_ERROR");
  else
    set_status(r, std::string(ret == SBA_ERROR ? "SBA_ERROR: " : "") + sba_reason(info[6]) + " (" +
                      std::to_string(static_cast<int>(info[6])) + ")");
}

// ---- Ceres ----

class TraceCallback final : public ceres::IterationCallback {
 public:
  TraceCallback(std::vector<std::array<double, 2>> *trace, double offset)
      : trace_(trace), offset_(offset) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary &s) override {
    trace_->push_back({offset_ + s.cumulative_time_in_seconds, 2.0 * s.cost});
    return ceres::SOLVER_CONTINUE;
  }

 private:
  std::vector<std::array<double, 2>> *trace_;
  double offset_;
};

template <int CNP>
void add_eucsba_residuals(const Problem &prob, double *p, ceres::Problem *cp) {
  const double *x = prob.x.data();
  double *pb = p + static_cast<std::size_t>(prob.m) * CNP;
  for (std::size_t k = 0; k < prob.nobs(); ++k) {
    const int j = prob.obs_camera[k], i = prob.obs_point[k];
    cp->AddResidualBlock(new EucsbaCost<CNP>(*prob.euc, j, x[2 * k], x[2 * k + 1]), nullptr,
                         p + static_cast<std::size_t>(j) * CNP, pb + static_cast<std::size_t>(i) * 3);
  }
}

void run_ceres(Problem &prob, const RunSpec &spec, int itmax, bool consume, RunResult *r,
               std::vector<std::array<double, 2>> *trace) {
  std::vector<double> p = initial_params(prob, consume);
  trace->reserve(static_cast<std::size_t>(itmax) + 2);
  r->hwm_reset = reset_peak_rss();
  r->base_rss = status_kb("VmRSS") * 1024;
  r->file_rss_start = file_rss();
  const double cpu0 = process_cpu_seconds();
  const auto t0 = std::chrono::steady_clock::now();

  ceres::Problem::Options po;
  po.enable_fast_removal = false;
  auto cp = std::make_unique<ceres::Problem>(po);
  const std::size_t m = static_cast<std::size_t>(prob.m), cnp = static_cast<std::size_t>(prob.cnp);
  double *pb = p.data() + m * cnp;
  if (prob.model_kind == ModelKind::Bal) {
    for (std::size_t k = 0; k < prob.nobs(); ++k)
      cp->AddResidualBlock(new BalCost(prob.x[2 * k], prob.x[2 * k + 1]), nullptr,
                           p.data() + static_cast<std::size_t>(prob.obs_camera[k]) * cnp,
                           pb + static_cast<std::size_t>(prob.obs_point[k]) * 3);
  } else if (cnp == 6) {
    add_eucsba_residuals<6>(prob, p.data(), cp.get());
  } else if (cnp == 11) {
    add_eucsba_residuals<11>(prob, p.data(), cp.get());
  } else {
    add_eucsba_residuals<16>(prob, p.data(), cp.get());
  }
  // Intrinsics the model holds (eucsbademo's nccalib / ncdist) are constants for Ceres too.
  const std::vector<int> held = prob.held_camera_params();
  if (!held.empty())
    for (std::size_t j = 0; j < m; ++j)
      cp->SetManifold(p.data() + j * cnp, new ceres::SubsetManifold(static_cast<int>(cnp), held));
  // Points first (eliminated), then cameras: the Schur complement sba forms.
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (int i = 0; i < prob.n; ++i) ordering->AddElementToGroup(pb + static_cast<std::size_t>(i) * 3, 0);
  for (std::size_t j = 0; j < m; ++j) ordering->AddElementToGroup(p.data() + j * cnp, 1);
  r->setup_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  // Ceres's defaults (Levenberg-Marquardt, its tolerances and trust-region settings) but for
  // what a bundle adjustment user sets: the linear solver, the threads, the iteration limit
  // and the points-first elimination order.
  ceres::Solver::Options o;
  if (spec.solver == "DENSE_SCHUR") {
    o.linear_solver_type = ceres::DENSE_SCHUR;
  } else if (spec.solver == "SPARSE_SCHUR") {
    o.linear_solver_type = ceres::SPARSE_SCHUR;
  } else {
    o.linear_solver_type = ceres::ITERATIVE_SCHUR;
    o.preconditioner_type = ceres::SCHUR_JACOBI;
  }
  o.linear_solver_ordering = ordering;
  o.num_threads = spec.threads;
  o.max_num_iterations = itmax;
  if (spec.ceres_tight) {
    o.function_tolerance = 1e-12;
    o.gradient_tolerance = 1e-12;
    o.parameter_tolerance = 1e-12;
  }
  o.logging_type = ceres::SILENT;
  o.minimizer_progress_to_stdout = false;
  TraceCallback cb(trace, r->setup_seconds);
  o.callbacks.push_back(&cb);
  ceres::Solver::Summary summary;
  ceres::Solve(o, cp.get(), &summary);
  cp.reset();  // part of the solve's cost, as sba frees its workspace before returning
  r->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r->cpu_seconds = process_cpu_seconds() - cpu0;
  r->peak_rss = status_kb("VmHWM") * 1024;
  r->file_rss_end = file_rss();

  r->ok = summary.IsSolutionUsable();
  r->reason = summary.termination_type;
  r->linear_solves = summary.num_successful_steps + summary.num_unsuccessful_steps;
  r->iterations = r->linear_solves;
  r->threads_used = spec.threads;
  r->func_evals = summary.num_residual_evaluations;
  r->jac_evals = summary.num_jacobian_evaluations;
  r->init_err = 2.0 * summary.initial_cost;
  r->final_err = 2.0 * summary.final_cost;
  std::string msg = ceres::TerminationTypeToString(summary.termination_type);
  if (summary.message.find("Maximum number of iterations") != std::string::npos) msg += " (itmax)";
  set_status(r, msg);
  std::snprintf(r->message, sizeof r->message, "%s", summary.message.c_str());
}

// ---- running in a child ----

// OpenBLAS's pthread build runs worker threads of its own inside DPOTRF (sba's dense S) and
// inside CHOLMOD's supernodal BLAS calls (sba's sparse-chol, Ceres's SPARSE_SCHUR), one per
// core unless told otherwise, so a "1-thread" run would use every core there. Found at run
// time so that another BLAS (without this entry point) still works: null then.
using BlasSetThreads = void (*)(int);
BlasSetThreads blas_set_threads() {
  return reinterpret_cast<BlasSetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
}

// Whether any thread of this process but the calling one is running (state R in
// /proc/self/task/TID/stat).
bool other_threads_running() {
  const long self = syscall(SYS_gettid);
  DIR *dir = opendir("/proc/self/task");
  if (!dir) return false;
  bool running = false;
  while (const dirent *e = readdir(dir)) {
    const long tid = std::atol(e->d_name);
    if (tid <= 0 || tid == self) continue;
    char path[64], buf[512];
    std::snprintf(path, sizeof path, "/proc/self/task/%ld/stat", tid);
    std::FILE *f = std::fopen(path, "r");
    if (!f) continue;
    const std::size_t len = std::fread(buf, 1, sizeof buf - 1, f);
    std::fclose(f);
    buf[len] = '\0';
    const char *close = std::strrchr(buf, ')');  // the state follows the command's ")"
    if (close && close[1] == ' ' && close[2] == 'R') running = true;
  }
  closedir(dir);
  return running;
}

// openblas_set_num_threads starts OpenBLAS's worker threads in this (forked) child, and
// each of them spins for about 0.1 s of CPU time before it sleeps. A run started at once
// would share the cores with them, and a 1-thread run would use more than one core.
// Real programs meet those threads asleep unless they have just called the BLAS, so the
// run waits (at most a second) until they are.
void wait_for_idle_threads() {
  for (int k = 0; k < 500 && other_threads_running(); ++k)
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
}

void execute(Problem &prob, const RunSpec &spec, int itmax, bool consume, RunResult *r,
             std::vector<std::array<double, 2>> *trace) {
  if (spec.blas_threads > 0)
    if (BlasSetThreads set = blas_set_threads()) {
      set(spec.blas_threads);
      wait_for_idle_threads();
    }
  try {
    if (spec.engine == Engine::Sba) run_sba(prob, spec, itmax, consume, r, trace);
    else run_ceres(prob, spec, itmax, consume, r, trace);
  } catch (const std::bad_alloc &) {
    r->ok = 0;
    set_status(r, "out of memory");
  } catch (const std::exception &e) {
    r->ok = 0;
    set_status(r, std::string("exception: ") + e.what());
  }
  r->ntrace = static_cast<int>(trace->size());
}

// Frees what the run does not use, so that the child's RSS is the run's: both sba (through
// its _vis entry point) and Ceres take the observation index, neither the dense vmask.
void release_unused(Problem &prob, Engine) {
  std::vector<char>().swap(prob.vmask);
  malloc_trim(0);
}

bool write_all(int fd, const void *data, std::size_t size) {
  const char *p = static_cast<const char *>(data);
  while (size > 0) {
    const ssize_t w = ::write(fd, p, size);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    p += w;
    size -= static_cast<std::size_t>(w);
  }
  return true;
}

// One iteration of the run, its memory handed back: the pages of code (and the threads) the
// measured solve will use are in place before its peak is reset.
void warm_up(Problem &prob, const RunSpec &spec) {
  RunResult r;
  std::vector<std::array<double, 2>> trace;
  execute(prob, spec, 1, false, &r, &trace);
  malloc_trim(0);
}

Run run_forked(Problem &prob, const RunSpec &spec, int itmax, double timeout, bool warm) {
  Run run;
  run.spec = spec;
  int fds[2];
  if (::pipe(fds) != 0) {
    set_status(&run.r, std::string("pipe: ") + std::strerror(errno));
    return run;
  }
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    set_status(&run.r, std::string("fork: ") + std::strerror(errno));
    ::close(fds[0]);
    ::close(fds[1]);
    return run;
  }
  if (pid == 0) {
    ::close(fds[0]);
    release_unused(prob, spec.engine);
    if (warm) warm_up(prob, spec);
    RunResult r;
    std::vector<std::array<double, 2>> trace;
    execute(prob, spec, itmax, true, &r, &trace);
    const bool ok = write_all(fds[1], &r, sizeof r) &&
                    write_all(fds[1], trace.data(), trace.size() * sizeof(trace[0]));
    ::close(fds[1]);
    ::_exit(ok ? 0 : 3);
  }
  ::close(fds[1]);
  std::vector<char> bytes;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout);
  bool timed_out = false;
  for (;;) {
    const double left = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0) {
      timed_out = true;
      break;
    }
    pollfd pfd{fds[0], POLLIN, 0};
    const int pr = ::poll(&pfd, 1, static_cast<int>(std::min(left * 1000.0 + 1, 60000.0)));
    if (pr < 0 && errno == EINTR) continue;
    if (pr <= 0) continue;
    char buf[65536];
    const ssize_t got = ::read(fds[0], buf, sizeof buf);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) break;
    bytes.insert(bytes.end(), buf, buf + got);
  }
  ::close(fds[0]);
  if (timed_out) ::kill(pid, SIGKILL);
  int wstatus = 0;
  rusage ru{};
  while (::wait4(pid, &wstatus, 0, &ru) < 0 && errno == EINTR) {
  }
  run.child_maxrss = static_cast<long long>(ru.ru_maxrss) * 1024;
  if (timed_out) {
    set_status(&run.r, "timeout after " + std::to_string(static_cast<long>(timeout)) + " s");
    return run;
  }
  if (bytes.size() < sizeof(RunResult)) {
    std::string why = "child failed";
    if (WIFSIGNALED(wstatus)) why += std::string(": signal ") + strsignal(WTERMSIG(wstatus));
    else if (WIFEXITED(wstatus)) why += ": exit " + std::to_string(WEXITSTATUS(wstatus));
    set_status(&run.r, why);
    return run;
  }
  std::memcpy(&run.r, bytes.data(), sizeof(RunResult));
  const std::size_t ntrace = (bytes.size() - sizeof(RunResult)) / sizeof(run.trace[0]);
  run.trace.resize(ntrace);
  if (ntrace > 0) std::memcpy(run.trace.data(), bytes.data() + sizeof(RunResult), ntrace * sizeof(run.trace[0]));
  return run;
}

Run run_inline(Problem &prob, const RunSpec &spec, int itmax, bool warm) {
  Run run;
  run.spec = spec;
  if (warm) warm_up(prob, spec);
  execute(prob, spec, itmax, false, &run.r, &run.trace);
  return run;
}

// ---- output ----

std::string json_string(const std::string &s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

std::string fmt(const char *format, double v) {
  if (!std::isfinite(v)) return "-";
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

struct ProblemFacts {
  long long pairs = 0;
  double jac_bytes = 0, s_dense_bytes = 0, s_sparse_bytes = 0, input_bytes = 0;
  // RssAnon of this program before it read the problem: the C++ runtime's, the libraries'
  // and the BLAS's own data, the same for every problem.
  long long program_anon = -1;
};

const Run *find_sba(const std::vector<Run> &runs, const std::string &solver, int threads) {
  for (const Run &r : runs)
    if (r.spec.engine == Engine::Sba && r.spec.solver == solver && r.spec.strategy == "sba" &&
        r.spec.threads == threads && r.r.ok)
      return &r;
  return nullptr;
}

// The peer a run is compared with: the fastest Ceres configuration at the same thread count.
const Run *best_ceres(const std::vector<Run> &runs, int threads) {
  const Run *best = nullptr;
  for (const Run &r : runs)
    if (r.spec.engine == Engine::Ceres && r.spec.threads == threads && r.r.ok &&
        (!best || r.r.seconds < best->r.seconds))
      best = &r;
  return best;
}

double ratio(double a, double b) { return (std::isfinite(a) && std::isfinite(b) && b > 0) ? a / b : NAN; }

int bench_main(int argc, char **argv) {
  Options o;
  std::string error;
  if (!parse_command_line(argc, argv, &o, &error)) {
    std::fprintf(stderr, "sba_bench: %s\n", error.c_str());
    return sbacli::kExitUsage;
  }
  if (o.help) {
    print_usage(stdout);
    return 0;
  }
  if (o.version) {
    std::printf("%s\n", sbacli::version_line("sba_bench").c_str());
    return 0;
  }

  ProblemFacts facts;
  facts.program_anon = status_kb("RssAnon");
  if (facts.program_anon > 0) facts.program_anon *= 1024;
  Problem prob;
  prob.name = o.name;
  const auto load_start = std::chrono::steady_clock::now();
  bool loaded = false;
  if (!o.bal.empty()) loaded = load_bal(o.bal, &prob, &error);
  else if (!o.gen.empty()) loaded = generate(o.gen, &prob, &error);
  else loaded = load_eucsba(o.cams, o.pts, o.calib, &prob, &error);
  if (!loaded) {
    std::fprintf(stderr, "sba_bench: %s\n", error.c_str());
    return 1;
  }
  const double load_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - load_start).count();

  const double nobs = static_cast<double>(prob.nobs());
  facts.pairs = prob.camera_pairs();
  facts.jac_bytes = nobs * Problem::mnp * (prob.cnp + Problem::pnp) * 8.0;
  facts.s_dense_bytes = std::pow(static_cast<double>(prob.m) * prob.cnp, 2) * 8.0;
  facts.s_sparse_bytes = static_cast<double>(facts.pairs) * prob.cnp * prob.cnp * 8.0;
  // x, the (point, camera) pairs and p: both engines take the pairs, no n*m vmask is held.
  facts.input_bytes = nobs * (2 * 8.0 + 2 * 4.0) + prob.nvars() * 8.0;
  malloc_trim(0);

  std::printf("problem %s (%s): %d cameras, %d points, %.0f observations, cnp %d, %lld variables\n",
              prob.name.c_str(), prob.description.c_str(), prob.m, prob.n, nobs, prob.cnp, prob.nvars());
  std::printf("  loaded in %.2f s; S has %lld nonzero camera blocks (upper, of %lld); J %.1f MB, dense S %.1f MB, "
              "sparse S %.1f MB, inputs %.1f MB; %d hardware threads\n",
              load_seconds, facts.pairs, static_cast<long long>(prob.m) * (prob.m + 1) / 2, facts.jac_bytes / 1e6,
              facts.s_dense_bytes / 1e6, facts.s_sparse_bytes / 1e6, facts.input_bytes / 1e6, hardware_threads());
  std::fflush(stdout);

  const bool blas_settable = blas_set_threads() != nullptr;
  std::printf("  BLAS threads: %s\n", !o.blas_same ? "left to the BLAS (--blas-threads default)"
                                       : blas_settable ? "as many as the run's threads (openblas_set_num_threads)"
                                                       : "left to the BLAS (no openblas_set_num_threads in this BLAS)");
  // The library also turns it on for SBA_AVOID_SHARED_CORES=1: a run says what it measured.
  const char *avoid_env = std::getenv("SBA_AVOID_SHARED_CORES");
  const bool avoid_from_env = avoid_env && std::string(avoid_env) == "1";
  const bool avoid = o.avoid_shared_cores || avoid_from_env;
  std::printf("  sba thread placement: %s\n",
              o.avoid_shared_cores ? "avoid_shared_cores on (--avoid-shared-cores)"
              : avoid_from_env     ? "avoid_shared_cores on (SBA_AVOID_SHARED_CORES=1 in the environment)"
                                   : "avoid_shared_cores off (the library's default: no affinity changes)");
  std::vector<RunSpec> specs;
  for (std::size_t k = 0; k < o.threads.size(); ++k) {
    const int t = o.threads[k];
    const bool all = o.threads_auto[k] != 0;
    const int bt = o.blas_same && blas_settable ? t : 0;
    for (const std::string &s : o.solvers)
      for (const std::string &st : o.strategies) specs.push_back({Engine::Sba, s, t, all, bt, avoid, st});
    for (const std::string &c : o.ceres) {
      const char *name = c == "dense" ? "DENSE_SCHUR" : c == "sparse" ? "SPARSE_SCHUR" : "ITERATIVE_SCHUR";
      specs.push_back({Engine::Ceres, name, t, all, bt, false, "", o.ceres_tight});
    }
  }

  // Rounds of every configuration rather than N runs of one after another, so that a slow
  // spell of the machine falls on all of them alike; each keeps its median-time run.
  std::vector<std::vector<Run>> reps(specs.size());
  for (int round = 0; round < o.repeat; ++round)
    for (std::size_t k = 0; k < specs.size(); ++k) {
      const RunSpec &spec = specs[k];
      std::fprintf(stderr, "sba_bench: %s: %s, %d thread%s", prob.name.c_str(), spec.label().c_str(), spec.threads,
                   spec.threads == 1 ? "" : "s");
      if (o.repeat > 1) std::fprintf(stderr, " (round %d of %d)", round + 1, o.repeat);
      std::fputs(" ... ", stderr);
      std::fflush(stderr);
      reps[k].push_back(o.fork ? run_forked(prob, spec, o.itmax, o.timeout, o.warm_up)
                                : run_inline(prob, spec, o.itmax, o.warm_up));
      const Run &r = reps[k].back();
      if (r.r.ok)
        std::fprintf(stderr, "%s, %.3f s, final MSE %.6g\n", r.r.status, r.r.seconds, r.r.final_err / nobs);
      else
        std::fprintf(stderr, "%s%s%s\n", r.r.status, r.r.message[0] ? ": " : "", r.r.message);
    }
  std::vector<Run> runs;
  for (std::vector<Run> &rs : reps) {
    std::vector<double> times;
    for (const Run &r : rs) times.push_back(r.r.ok ? r.r.seconds : NAN);
    // A failed repetition is what gets reported; else the (lower) median.
    std::size_t pick = 0;
    const auto failed = std::find_if(rs.begin(), rs.end(), [](const Run &r) { return !r.r.ok; });
    if (failed != rs.end()) {
      pick = static_cast<std::size_t>(failed - rs.begin());
    } else {
      std::vector<std::size_t> order(rs.size());
      for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
      std::sort(order.begin(), order.end(), [&times](std::size_t a, std::size_t b) { return times[a] < times[b]; });
      pick = order[(order.size() - 1) / 2];
    }
    runs.push_back(std::move(rs[pick]));
    runs.back().all_seconds = times;
  }

  // Time to the best final error over every run.
  double best = INFINITY;
  for (const Run &r : runs)
    if (r.r.ok && std::isfinite(r.r.final_err)) best = std::min(best, r.r.final_err);
  for (Run &r : runs) {
    if (!r.r.ok) continue;
    for (const auto &pt : r.trace)
      if (pt[1] <= best * (1 + kBestTolerance)) {
        r.ttb = pt[0];
        break;
      }
  }

  std::printf("  best final MSE %.8g; vsCer: time and time to best against the fastest Ceres run\n"
              "  with the same threads; '!' after it: the run ended at a worse error than that Ceres\n"
              "  run (beyond %g relative), no win whatever its time; it/chol: time per iteration\n"
              "  against sba chol\n",
              best / nobs, kBestTolerance);
  std::printf("  %-30s %3s %-26s %5s %6s %9s %9s %11s %11s %9s %9s %9s %9s %8s\n", "run", "thr", "status",
              "iters", "linsys", "time[s]", "ms/iter", "init MSE", "final MSE", "RSS[MB]", "vsCer", "ttb[s]",
              "ttbvsCer", "it/chol");
  FILE *out = nullptr;
  if (!o.out.empty()) {
    out = std::fopen(o.out.c_str(), "a");
    if (!out) std::fprintf(stderr, "sba_bench: %s: cannot open for appending: %s\n", o.out.c_str(), std::strerror(errno));
  }
  char stamp[32];
  const std::time_t now = std::time(nullptr);
  std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
  for (const Run &r : runs) {
    const RunResult &x = r.r;
    const double per_iter = x.ok && x.iterations > 0 ? x.seconds / x.iterations : NAN;
    const Run *cd = best_ceres(runs, r.spec.threads);
    const Run *chol = find_sba(runs, "chol", r.spec.threads);
    const double vs_cd = x.ok && cd ? ratio(x.seconds, cd->r.seconds) : NAN;
    const double ttb_vs_cd = x.ok && cd ? ratio(r.ttb, cd->ttb) : NAN;
    const bool worse = x.ok && cd && x.final_err > cd->r.final_err * (1 + kBestTolerance);
    const double it_vs_chol =
        x.ok && chol && r.spec.engine == Engine::Sba ? ratio(per_iter, chol->r.seconds / chol->r.iterations) : NAN;
    const double peak = x.peak_rss > 0 ? static_cast<double>(x.peak_rss) : static_cast<double>(r.child_maxrss);
    std::printf("  %-30s %3d %-26.26s %5d %6d %9s %9s %11s %11s %9s %9s %9s %9s %8s\n", r.spec.label().c_str(),
                x.threads_used > 0 ? x.threads_used : r.spec.threads, x.status, x.iterations, x.linear_solves, fmt("%.3f", x.ok ? x.seconds : NAN).c_str(),
                fmt("%.2f", per_iter * 1e3).c_str(), fmt("%.6g", x.ok ? x.init_err / nobs : NAN).c_str(),
                fmt("%.8g", x.ok ? x.final_err / nobs : NAN).c_str(), fmt("%.1f", peak / 1e6).c_str(),
                (fmt("%.2fx", vs_cd) + (worse ? "!" : "")).c_str(), fmt("%.3f", r.ttb).c_str(),
                fmt("%.2fx", ttb_vs_cd).c_str(),
                fmt("%.2fx", it_vs_chol).c_str());
    if (!out) continue;
    std::string j = "{";
    auto field = [&j](const char *k, const std::string &v) {
      if (j.size() > 1) j += ", ";
      j += json_string(k) + ": " + v;
    };
    field("time", json_string(stamp));
    field("problem", json_string(prob.name));
    field("description", json_string(prob.description));
    field("model", json_string(prob.model_kind == ModelKind::Bal ? "bal" : "eucsba"));
    field("cameras", std::to_string(prob.m));
    field("points", std::to_string(prob.n));
    field("observations", json_number(nobs));
    field("cnp", std::to_string(prob.cnp));
    field("variables", std::to_string(prob.nvars()));
    field("camera_pairs", std::to_string(facts.pairs));
    field("jacobian_bytes", json_number(facts.jac_bytes));
    field("dense_s_bytes", json_number(facts.s_dense_bytes));
    field("sparse_s_bytes", json_number(facts.s_sparse_bytes));
    field("input_bytes", json_number(facts.input_bytes));
    field("load_seconds", json_number(load_seconds));
    field("hardware_threads", std::to_string(hardware_threads()));
    field("engine", json_string(r.spec.engine == Engine::Sba ? "sba" : "ceres"));
    field("solver", json_string(r.spec.solver));
    field("strategy", r.spec.engine == Engine::Sba ? json_string(r.spec.strategy) : "null");
    field("ceres_tolerances", r.spec.engine == Engine::Ceres ? json_string(r.spec.ceres_tight ? "1e-12" : "default") : "null");
    field("threads", std::to_string(r.spec.threads));
    field("threads_auto", r.spec.auto_threads ? "true" : "false");
    field("threads_used", std::to_string(r.r.threads_used));
    field("blas_threads", r.spec.blas_threads > 0 ? std::to_string(r.spec.blas_threads) : "null");
    field("avoid_shared_cores", r.spec.engine != Engine::Sba ? "null" : r.spec.avoid_shared_cores ? "true" : "false");
    field("itmax", std::to_string(o.itmax));
    field("ok", x.ok ? "true" : "false");
    field("status", json_string(x.status));
    field("message", json_string(x.message));
    field("reason", json_number(x.reason));
    field("iterations", std::to_string(x.iterations));
    field("linear_solves", std::to_string(x.linear_solves));
    field("func_evals", std::to_string(x.func_evals));
    field("jac_evals", std::to_string(x.jac_evals));
    field("seconds", json_number(x.ok ? x.seconds : NAN));
    std::string all = "[";
    for (std::size_t k = 0; k < r.all_seconds.size(); ++k) all += (k ? ", " : "") + json_number(r.all_seconds[k]);
    field("repeats", std::to_string(r.all_seconds.size()));
    field("seconds_all", all + "]");
    field("setup_seconds", json_number(x.setup_seconds));
    field("cpu_seconds", json_number(x.ok ? x.cpu_seconds : NAN));
    field("seconds_per_iteration", json_number(per_iter));
    field("seconds_per_linear_solve",
          json_number(x.ok && x.linear_solves > 0 ? x.seconds / x.linear_solves : NAN));
    field("initial_mse", json_number(x.ok ? x.init_err / nobs : NAN));
    field("final_mse", json_number(x.ok ? x.final_err / nobs : NAN));
    field("best_final_mse", json_number(best / nobs));
    field("peak_rss_bytes", json_number(peak));
    field("base_rss_bytes", json_number(static_cast<double>(x.base_rss)));
    field("child_maxrss_bytes", json_number(static_cast<double>(r.child_maxrss)));
    auto bytes = [](long long b) { return json_number(b >= 0 ? static_cast<double>(b) : NAN); };  // -1: unknown
    field("file_rss_start_bytes", bytes(x.file_rss_start));
    field("file_rss_end_bytes", bytes(x.file_rss_end));
    field("program_anon_bytes", bytes(facts.program_anon));
    // What the problem and the solve hold: the peak less the code pages resident when the
    // solve started and the program's own data (see file_rss and ProblemFacts::program_anon).
    // Code first run during the solve counts as data: never an under-count.
    const bool parts = x.hwm_reset && x.peak_rss > 0 && x.file_rss_start >= 0 && facts.program_anon >= 0;
    field("data_peak_bytes",
          json_number(parts ? static_cast<double>(x.peak_rss - x.file_rss_start - facts.program_anon) : NAN));
    field("peak_rss_reset", x.hwm_reset ? "true" : "false");
    field("ceres_best_solver", cd ? json_string(cd->spec.solver) : "null");
    field("ceres_best_final_mse", json_number(cd ? cd->r.final_err / nobs : NAN));
    field("ratio_time_vs_ceres_best", json_number(vs_cd));
    field("worse_than_ceres_best", worse ? "true" : "false");
    field("time_to_best_seconds", json_number(r.ttb));
    field("ratio_time_to_best_vs_ceres_best", json_number(ttb_vs_cd));
    field("ratio_per_iteration_vs_chol", json_number(it_vs_chol));
    std::string tr = "[";
    for (std::size_t k = 0; k < r.trace.size(); ++k)
      tr += (k ? ", [" : "[") + json_number(r.trace[k][0]) + ", " + json_number(r.trace[k][1] / nobs) + "]";
    field("trace", tr + "]");
    std::fprintf(out, "%s}\n", j.c_str());
  }
  if (out) std::fclose(out);
  std::fflush(stdout);
  for (const Run &r : runs)
    if (!r.r.ok) return 1;
  return 0;
}

}  // namespace
}  // namespace sbabench

int main(int argc, char **argv) {
  google::InitGoogleLogging(argv[0]);
  try {
    return sbabench::bench_main(argc, argv);
  } catch (const std::bad_alloc &) {
    std::fprintf(stderr, "sba_bench: out of memory\n");
  } catch (const std::exception &e) {
    std::fprintf(stderr, "sba_bench: %s\n", e.what());
  }
  return 1;
}
