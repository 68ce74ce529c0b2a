// SPDX-License-Identifier: BSD-3-Clause
// sba_bench's sba engine: the problem through sba_motstr_levmar_x_vis, as its users call it.
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "bench_run.h"
#include "sba.h"
#include "sba_ext.h"

namespace sbabench {
namespace {

struct SbaTrace {
  Trace *trace;
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

}  // namespace

void run_sba(Problem &prob, const RunSpec &spec, int itmax, bool consume, RunResult *r,
             Trace *trace) {
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
  ext.single_precision_jacobian = spec.jacobian == "single";
  const sbacameras::euclidean::MotStrCallbacks simple = prob.simple();
  const int ret =
      spec.jacobian == "double"
          ? sba_motstr_levmar_x_vis(prob.n, 0, prob.m, 0, &vis, p.data(), prob.cnp, Problem::pnp, prob.x.data(),
                                    nullptr, Problem::mnp, prob.func(), prob.fjac(), prob.adata(), itmax, 0, nullptr,
                                    info.data(), &ext)
          : sba_motstr_levmar_vis(prob.n, 0, prob.m, 0, &vis, p.data(), prob.cnp, Problem::pnp, prob.x.data(),
                                  nullptr, Problem::mnp, simple.proj, simple.projac, prob.adata(), itmax, 0, nullptr,
                                  info.data(), &ext);
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

}  // namespace sbabench
