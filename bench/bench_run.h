// SPDX-License-Identifier: BSD-3-Clause
// sba_bench's runs: what one run is (RunSpec), what it measured (RunResult), the engines that
// run it (bench_sba.cpp, bench_ceres.cpp) and the process that hosts it, with its memory and
// CPU accounting (bench_process.cpp).
#ifndef SBA_BENCH_BENCH_RUN_H
#define SBA_BENCH_BENCH_RUN_H

#include <array>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "bench_problem.h"

namespace sbabench {

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
  // sba: "double" (the expert driver, as its users call it), "simple" (the simple driver's
  // per-projection callbacks) or "single" (those, with single_precision_jacobian).
  std::string jacobian = "double";
  std::string label() const {
    if (engine == Engine::Ceres) return "ceres " + solver + (ceres_tight ? " tight" : "");
    return "sba " + solver + (strategy == "sba" ? "" : " " + strategy) + (jacobian == "double" ? "" : " " + jacobian);
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
  // core_round_trip_ns just before and just after the solve (NaN: not measured)
  double core_rt_before = NAN, core_rt_after = NAN;
};

// (seconds since the solve started, ||e||^2) at each iteration.
using Trace = std::vector<std::array<double, 2>>;

struct Run {
  RunSpec spec;
  RunResult r;
  Trace trace;
  long long child_maxrss = 0;                // ru_maxrss of the child, bytes (cross-check)
  std::vector<double> all_seconds;           // every repetition's time (--repeat), in run order
  std::vector<std::array<double, 2>> all_core_rt;  // every repetition's core_rt_before/after
  double ttb = NAN;                          // time to best, seconds (NaN: never)
};

// ---- the process: its hardware, memory and CPU accounting (bench_process.cpp) ----

int hardware_threads();

// The mean time, in nanoseconds, for a cache line to go from one CPU to another and back:
// two short-lived threads, each held on one of the first two CPUs of this process's mask,
// take turns writing it. A virtual machine's two vCPUs can sit on one cache (tens of ns) or
// on two (hundreds), and the host can move them from one placement to the other at any time;
// a run's threads then exchange their data at that price. NaN with fewer than two CPUs.
double core_round_trip_ns();

// A field of /proc/self/status in kB; -1 if absent.
long long status_kb(const char *field);
// Resident pages backed by files: the code of the program and its libraries, which every
// process running them shares. Their count when a solve starts is a lower bound of their
// share of its peak (they are only added during a solve, nothing is unmapped); --warm-up
// makes it exact up to the code that only the measured solve runs.
long long file_rss();
// User + system time of every thread of this process so far.
double process_cpu_seconds();
// Resets VmHWM (the peak RSS) to the current RSS; false where the kernel does not allow it.
bool reset_peak_rss();
void set_status(RunResult *r, const std::string &s);

// The parameters a run refines: the problem's own in a child (which has no further use for
// them, and a copy would count against the run's memory), a copy otherwise.
inline std::vector<double> initial_params(Problem &prob, bool consume) {
  return consume ? std::move(prob.p0) : prob.p0;
}

// ---- the engines: one solve each, measured from the start of the call ----
void run_sba(Problem &prob, const RunSpec &spec, int itmax, bool consume, RunResult *r,
             Trace *trace);
void run_ceres(Problem &prob, const RunSpec &spec, int itmax, bool consume, RunResult *r,
               Trace *trace);

// ---- running a solve (bench_process.cpp) ----
// OpenBLAS's pthread build runs worker threads of its own inside DPOTRF (sba's dense S) and
// inside CHOLMOD's supernodal BLAS calls (sba's sparse-chol, Ceres's SPARSE_SCHUR), one per
// core unless told otherwise, so a "1-thread" run would use every core there. Found at run
// time so that another BLAS (without this entry point) still works: null then.
using BlasSetThreads = void (*)(int);
BlasSetThreads blas_set_threads();

// The run in a child process (its peak RSS its own), killed after timeout seconds; warm: one
// iteration first, its memory handed back.
Run run_forked(Problem &prob, const RunSpec &spec, int itmax, double timeout, bool warm);
// The run in this process (--no-fork).
Run run_inline(Problem &prob, const RunSpec &spec, int itmax, bool warm);

}  // namespace sbabench

#endif
