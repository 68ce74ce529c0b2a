// SPDX-License-Identifier: BSD-3-Clause
// sba_bench's Ceres engine: the same problem built as a ceres::Problem (same camera model, same
// analytic Jacobian, same parameters) and solved at Ceres's default options but for what a
// bundle adjustment user sets.
#include <array>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <ceres/ceres.h>

#include "bench_run.h"
#include "ceres_models.h"

namespace sbabench {
namespace {

class TraceCallback final : public ceres::IterationCallback {
 public:
  TraceCallback(Trace *trace, double offset)
      : trace_(trace), offset_(offset) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary &s) override {
    trace_->push_back({offset_ + s.cumulative_time_in_seconds, 2.0 * s.cost});
    return ceres::SOLVER_CONTINUE;
  }

 private:
  Trace *trace_;
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

}  // namespace

void run_ceres(Problem &prob, const RunSpec &spec, int itmax, bool consume, RunResult *r,
               Trace *trace) {
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

}  // namespace sbabench
