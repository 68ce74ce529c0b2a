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
//
// The files: this one (the command line, the rounds of runs and the report), bench_run.h (a
// run), bench_sba.cpp and bench_ceres.cpp (the two engines), bench_process.cpp (the child
// process and the memory and CPU accounting), bench_json.cpp (the JSON records).
#include <malloc.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include <ceres/ceres.h>

#include "bench_json.h"
#include "bench_problem.h"
#include "bench_run.h"
#include "cli/cli.h"

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
  std::vector<std::string> jacobians{"double"};
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
  t.push_back({"jacobian", "LIST",
               "how sba gets and stores the Jacobian, comma-separated (default double): double (the\n"
               "expert driver), simple (the simple driver, per projection), single (the simple\n"
               "driver with the Jacobian stored in single precision)",
               [&o](const std::string &v) -> std::string {
                 std::vector<std::string> names = split(v);
                 for (const std::string &item : names)
                   if (item != "double" && item != "simple" && item != "single")
                     return "'" + item + "': expected double, simple or single";
                 if (names.empty()) return "expected double, simple or single, comma-separated";
                 o.jacobians = names;
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
  t.push_back({"no-fork", "",
               "run in this process (peak RSS then is the process's; the round trips between CPUs are\n"
               "not measured)",
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

// ---- the report ----

std::string fmt(const char *format, double v) {
  if (!std::isfinite(v)) return "-";
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

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

// Loads (or generates) the problem of the command line and measures what the report says of
// it; false (with *error) if it cannot be had.
bool load_problem(const Options &o, Problem *prob, ProblemFacts *facts, std::string *error) {
  facts->program_anon = status_kb("RssAnon");
  if (facts->program_anon > 0) facts->program_anon *= 1024;
  prob->name = o.name;
  const auto load_start = std::chrono::steady_clock::now();
  bool loaded = false;
  if (!o.bal.empty()) loaded = load_bal(o.bal, prob, error);
  else if (!o.gen.empty()) loaded = generate(o.gen, prob, error);
  else loaded = load_eucsba(o.cams, o.pts, o.calib, prob, error);
  if (!loaded) return false;
  facts->load_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - load_start).count();

  const double nobs = static_cast<double>(prob->nobs());
  facts->pairs = prob->camera_pairs();
  facts->jac_bytes = nobs * Problem::mnp * (prob->cnp + Problem::pnp) * 8.0;
  facts->s_dense_bytes = std::pow(static_cast<double>(prob->m) * prob->cnp, 2) * 8.0;
  facts->s_sparse_bytes = static_cast<double>(facts->pairs) * prob->cnp * prob->cnp * 8.0;
  // x, the (point, camera) pairs and p: both engines take the pairs, no n*m vmask is held.
  facts->input_bytes = nobs * (2 * 8.0 + 2 * 4.0) + prob->nvars() * 8.0;
  malloc_trim(0);
  return true;
}

void print_problem(const Problem &prob, const ProblemFacts &facts) {
  std::printf("problem %s (%s): %d cameras, %d points, %.0f observations, cnp %d, %lld variables\n",
              prob.name.c_str(), prob.description.c_str(), prob.m, prob.n, static_cast<double>(prob.nobs()),
              prob.cnp, prob.nvars());
  std::printf("  loaded in %.2f s; S has %lld nonzero camera blocks (upper, of %lld); J %.1f MB, dense S %.1f MB, "
              "sparse S %.1f MB, inputs %.1f MB; %d hardware threads\n",
              facts.load_seconds, facts.pairs, static_cast<long long>(prob.m) * (prob.m + 1) / 2,
              facts.jac_bytes / 1e6, facts.s_dense_bytes / 1e6, facts.s_sparse_bytes / 1e6,
              facts.input_bytes / 1e6, hardware_threads());
  std::fflush(stdout);
}

// Every configuration the command line asks for, each run's BLAS threads and sba's thread
// placement said on stdout.
std::vector<RunSpec> make_specs(const Options &o) {
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
      for (const std::string &st : o.strategies)
        for (const std::string &jac : o.jacobians) {
          specs.push_back({Engine::Sba, s, t, all, bt, avoid, st});
          specs.back().jacobian = jac;
        }
    for (const std::string &c : o.ceres) {
      const char *name = c == "dense" ? "DENSE_SCHUR" : c == "sparse" ? "SPARSE_SCHUR" : "ITERATIVE_SCHUR";
      specs.push_back({Engine::Ceres, name, t, all, bt, false, "", o.ceres_tight});
    }
  }
  return specs;
}

// Rounds of every configuration rather than N runs of one after another, so that a slow
// spell of the machine falls on all of them alike; each keeps its median-time run.
std::vector<Run> run_rounds(const Options &o, Problem &prob, const std::vector<RunSpec> &specs) {
  const double nobs = static_cast<double>(prob.nobs());
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
      if (r.r.ok) {
        std::fprintf(stderr, "%s, %.3f s, final MSE %.6g", r.r.status, r.r.seconds, r.r.final_err / nobs);
        if (o.fork) std::fprintf(stderr, ", core round trip %.0f/%.0f ns", r.r.core_rt_before, r.r.core_rt_after);
        std::fputc('\n', stderr);
      } else {
        std::fprintf(stderr, "%s%s%s\n", r.r.status, r.r.message[0] ? ": " : "", r.r.message);
      }
    }
  std::vector<Run> runs;
  for (std::vector<Run> &rs : reps) {
    std::vector<double> times;
    std::vector<std::array<double, 2>> core_rt;
    for (const Run &r : rs) {
      times.push_back(r.r.ok ? r.r.seconds : NAN);
      core_rt.push_back({r.r.core_rt_before, r.r.core_rt_after});
    }
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
    runs.back().all_core_rt = core_rt;
  }
  return runs;
}

// The best final error over every run, and each run's time to it.
double mark_time_to_best(std::vector<Run> &runs) {
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
  return best;
}

Comparison compare(const std::vector<Run> &runs, const Run &r) {
  const RunResult &x = r.r;
  Comparison c;
  c.per_iter = x.ok && x.iterations > 0 ? x.seconds / x.iterations : NAN;
  c.ceres = best_ceres(runs, r.spec.threads);
  const Run *chol = find_sba(runs, "chol", r.spec.threads);
  c.vs_ceres = x.ok && c.ceres ? ratio(x.seconds, c.ceres->r.seconds) : NAN;
  c.ttb_vs_ceres = x.ok && c.ceres ? ratio(r.ttb, c.ceres->ttb) : NAN;
  c.worse = x.ok && c.ceres && x.final_err > c.ceres->r.final_err * (1 + kBestTolerance);
  c.it_vs_chol =
      x.ok && chol && r.spec.engine == Engine::Sba ? ratio(c.per_iter, chol->r.seconds / chol->r.iterations) : NAN;
  c.peak = x.peak_rss > 0 ? static_cast<double>(x.peak_rss) : static_cast<double>(r.child_maxrss);
  return c;
}

// The table on stdout and, with --out, one JSON record per run appended to that file.
void report(const Options &o, const Problem &prob, const ProblemFacts &facts, const std::vector<Run> &runs,
            double best) {
  const double nobs = static_cast<double>(prob.nobs());
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
    const Comparison c = compare(runs, r);
    std::printf("  %-30s %3d %-26.26s %5d %6d %9s %9s %11s %11s %9s %9s %9s %9s %8s\n", r.spec.label().c_str(),
                x.threads_used > 0 ? x.threads_used : r.spec.threads, x.status, x.iterations, x.linear_solves,
                fmt("%.3f", x.ok ? x.seconds : NAN).c_str(), fmt("%.2f", c.per_iter * 1e3).c_str(),
                fmt("%.6g", x.ok ? x.init_err / nobs : NAN).c_str(),
                fmt("%.8g", x.ok ? x.final_err / nobs : NAN).c_str(), fmt("%.1f", c.peak / 1e6).c_str(),
                (fmt("%.2fx", c.vs_ceres) + (c.worse ? "!" : "")).c_str(), fmt("%.3f", r.ttb).c_str(),
                fmt("%.2fx", c.ttb_vs_ceres).c_str(), fmt("%.2fx", c.it_vs_chol).c_str());
    if (out) std::fprintf(out, "%s\n", json_record(stamp, prob, facts, r, c, o.itmax, best).c_str());
  }
  if (out) std::fclose(out);
  std::fflush(stdout);
}

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
  Problem prob;
  if (!load_problem(o, &prob, &facts, &error)) {
    std::fprintf(stderr, "sba_bench: %s\n", error.c_str());
    return 1;
  }
  print_problem(prob, facts);
  const std::vector<RunSpec> specs = make_specs(o);
  std::vector<Run> runs = run_rounds(o, prob, specs);
  const double best = mark_time_to_best(runs);
  report(o, prob, facts, runs, best);
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
