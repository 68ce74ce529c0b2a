// SPDX-License-Identifier: BSD-3-Clause
// The C boundary's driver calls: parse (the entry points in c_api.cpp build DriverArgs),
// validate (the problem's sizes and pointers, the options, then the data once laid out), lay
// out, solve. Nothing escapes a call as an exception and info is filled on every return path;
// only a forced unwind (the calling thread ended by pthread_exit or pthread_cancel in a
// callback) passes through, freeing everything on its way (catch_all in log.h).
#include "driver.h"

#include <algorithm>
#include <cfloat>
#include <cstddef>
#include <cstring>
#include <memory>
#include <string>

#include "camera_unknowns.h"
#include "covariance.h"
#include "driver_options.h"
#include "finite.h"
#include "jacobian_check.h"
#include "linear_solver.h"
#include "lm.h"
#include "log.h"
#include "model.h"
#include "options.h"
#include "priors.h"
#include "solver_choice.h"
#include "step_solver.h"
#include "strategy.h"
#include "thread_policy.h"
#include "unknowns.h"

namespace sba {

namespace {

// The problem's sizes and pointers, what can be checked before the options and the index
// exist. Empty string: all good.
std::string check_problem(const DriverArgs &a) {
  auto positive = [](const char *what, int v) {
    return what + std::string(" must be positive (got ") + std::to_string(v) + ")";
  };
  if (a.n <= 0) return positive("n", a.n);
  if (a.m <= 0) return positive("m", a.m);
  if (a.mode != Mode::Str && a.cnp <= 0) return positive("cnp", a.cnp);
  if (a.mode != Mode::Mot && a.pnp <= 0) return positive("pnp", a.pnp);
  if (a.mnp <= 0) return positive("mnp", a.mnp);
  if (a.mcon < 0 || a.mcon > a.m)
    return "mcon must be in [0, m] = [0, " + std::to_string(a.m) + "] (got " +
           std::to_string(a.mcon) + ")";
  if (a.ncon < 0 || a.ncon > a.n)
    return "ncon must be in [0, n] = [0, " + std::to_string(a.n) + "] (got " +
           std::to_string(a.ncon) + ")";
  if (a.by_pairs ? !a.vis : !a.vmask) return a.by_pairs ? "vis is NULL" : "vmask is NULL";
  if (!a.p) return "p is NULL";
  if (!a.x) return "x is NULL";
  if (!a.callbacks.has_projection()) return "the projection function (func or proj) is NULL";
  return {};
}

// The index from vmask or from the pairs; msg set on failure.
void make_layout(const DriverArgs &a, Layout &lay, std::string *msg) {
  const int cnp = a.mode == Mode::Str ? 0 : a.cnp, pnp = a.mode == Mode::Mot ? 0 : a.pnp;
  const bool ok = a.by_pairs
                      ? build_layout(lay, a.mode, a.n, a.m, a.mcon, a.ncon, cnp, pnp, a.mnp, *a.vis, msg,
                                     a.covx != nullptr)
                      : build_layout(lay, a.mode, a.n, a.m, a.mcon, a.ncon, cnp, pnp, a.mnp, a.vmask, msg,
                                     a.covx != nullptr);
  if (!ok && msg->empty()) *msg = "invalid problem";
}

// The data once the index (and the camera map) says how much of it there is; the priors'
// residuals count as measurements.
std::string check_data(const DriverArgs &a, const Layout &lay, const Options &opt) {
  const i64 nobs = lay.nvis * lay.mnp + opt.priors.rows(lay);
  if (lay.free_vars() == 0) return "every camera and point is fixed (mcon/ncon): nothing to refine";
  const i64 unknowns = count_unknowns(lay);
  if (unknowns == 0) return "every parameter is fixed (mcon/ncon) or held (cam_fixed): nothing to refine";
  if (nobs < unknowns)
    return "fewer measurements (" + std::to_string(nobs) + ") than free parameters (" + std::to_string(unknowns) +
           ")";
  i64 bad = first_nonfinite(a.p, lay.nvars());
  if (bad >= 0) return "p[" + std::to_string(bad) + "] is not finite";
  bad = first_nonfinite(a.x, lay.nvis * lay.mnp);
  if (bad >= 0) return "x[" + std::to_string(bad) + "] is not finite";
  if (a.covx) {
    bad = first_nonfinite(a.covx, lay.nvis * lay.mnp * lay.mnp);
    if (bad >= 0) return "covx[" + std::to_string(bad) + "] is not finite";
  }
  return {};
}

void quiet_sink(void *, int, const char *) {}

Logger make_logger(const DriverArgs &a, const sba_ext_options &ext) {
  return Logger(a.verbose, ext.quiet ? quiet_sink : ext.log, ext.quiet ? nullptr : ext.log_ctx);
}

// Everything a call checks and builds before its model exists, in this order: the problem,
// the options' names, what the entry point itself asks (`extra`, once the options are known),
// the index, the options' values (Options::is_valid, which needs the index for the held and
// shared camera parameters), the data; then the thread count fitted to the problem. Logs the
// first problem found and returns false.
template <class Extra>
bool validate_and_lay_out(const DriverArgs &a, const sba_ext_options &ext, const Environment &env,
                          const Logger &log, Extra extra, Options *opt, Layout *lay) {
  std::string msg = check_problem(a);
  if (msg.empty()) options_from(a, ext, env, log, opt, &msg);
  if (msg.empty()) msg = extra();
  if (msg.empty()) make_layout(a, *lay, &msg);
  // The index's val array is for the expert callbacks alone (their idxij): 4 bytes per
  // projection that a simple driver's solve does without.
  if (msg.empty() && a.callbacks.simple) {
    std::vector<int>().swap(lay->val);
    lay->idx.val = nullptr;
  }
  if (msg.empty()) opt->is_valid(*lay, a.p, &msg);
  if (msg.empty()) {
    lay->cams = make_camera_map(opt->cams, *lay);
    msg = check_single_jacobian(*opt, *lay, a.callbacks.simple);
    if (msg.empty()) msg = check_data(a, *lay, *opt);
  }
  if (!msg.empty()) {
    log.error("%s: %s", a.name, msg.c_str());
    return false;
  }
  opt->nthreads = fit_threads(lay->nvis, opt->nthreads, opt->auto_threads);
  return true;
}

// "auto" made the solver it stands for, from the problem as laid out and the memory budget
// (solver_choice.h), and said when verbose: the report names the solver that ran, this line
// why. False, said, when even the solver that needs least does not fit the budget.
bool resolve_auto(const DriverArgs &a, const Layout &lay, const Logger &log, Options *opt) {
  if (opt->solver != LinSolver::Auto) return true;
  const MemoryBudget budget = memory_budget(opt->memory_budget);
  SolverShape shape = shape_of(lay, budget.bytes);
  if (opt->single_jacobian) shape.jacobian_entry_bytes = int(sizeof(float));
  // As lm_core.cpp's Workspace and validate_and_lay_out keep them.
  shape.residual_kept = !(opt->single_jacobian && a.callbacks.per_projection.projac);
  shape.expert_index = !a.callbacks.simple;
  opt->solver = choose_linsolver(shape);
  if (opt->solver == LinSolver::SparseChol) opt->schur_analysis = shape.analysis;
  const double needs = solver_bytes(shape, opt->solver);
  if (budget.bytes > 0 && needs > budget.bytes) {
    const auto mib = [](double bytes) { return bytes / (1024.0 * 1024.0); };
    log.error("%s: linear solver auto: the leanest solver for this problem, %s, needs about %.0f MiB, more than "
              "the budget of %.0f MiB (%s)",
              a.name, linsolver_name(opt->solver), mib(needs), mib(budget.bytes), budget.what);
    return false;
  }
  if (log.verbose() > 0)
    log.info(1, "%s: linear solver auto: %s (%s, %s)", a.name, linsolver_name(opt->solver), describe(shape).c_str(),
             budget.what);
  return true;
}

// The solver that runs, which the result names: one small Cholesky per block where the system
// is block diagonal, whatever was asked; else the one asked for, auto resolved.
bool choose_solver(const DriverArgs &a, const Layout &lay, const Logger &log, Options *opt) {
  if (!block_diagonal(lay)) return resolve_auto(a, lay, log, opt);
  if (log.verbose() > 0)
    log.info(1, "%s: linear solver: block-diagonal, %s asked (no free %s: each %s's step is solved alone)", a.name,
             linsolver_name(opt->solver), lay.free_cams() == 0 ? "cameras" : "points",
             lay.free_cams() == 0 ? "point" : "camera");
  opt->solver = LinSolver::BlockDiagonal;
  return true;
}

// The caller's result struct, filled as far as the caller's struct goes.
void write_result(const sba_ext_options &ext, const Options &opt, const Summary &sum) {
  if (!ext.result || ext.result->size < sizeof(size_t)) return;
  sba_ext_result r;
  sba_ext_result_init(&r);
  r.sq_error_initial = sum.sq_err0;
  r.sq_error_final = sum.sq_err;
  r.cost_initial = sum.err0;
  r.cost_final = sum.err;
  r.outliers_final = sum.outliers;
  r.nthreads = opt.nthreads;
  r.linsolver = linsolver_name(opt.solver);
  r.robust = opt.loss.robust();
  r.strategy = strategy_name(opt.strategy);
  r.projection_cost_initial = sum.proj_err0;
  r.projection_cost_final = sum.proj_err;
  r.prior_cost_initial = sum.prior_err0;
  r.prior_cost_final = sum.prior_err;
  const size_t n = std::min(ext.result->size, sizeof r);
  r.size = ext.result->size;
  std::memcpy(static_cast<void *>(ext.result), &r, n);
}

// info[7..9] as sba 1.6 counts them: each func or fjac call of a simple driver is nvis proj or
// projac calls, and the motion-only and structure-only drivers solve one small system per free
// camera (point) where the others solve one augmented system.
void count_as_1_6(const DriverArgs &a, const Layout &lay, Summary &sum) {
  if (a.callbacks.simple) {
    sum.nfev *= lay.nvis;
    sum.njev *= lay.nvis;
  }
  if (a.mode == Mode::Mot) sum.nlinsys *= lay.free_cams();
  if (a.mode == Mode::Str) sum.nlinsys *= lay.free_pts();
}

// The covariance request, checked and copied; empty string: all good.
std::string check_request(const DriverArgs &a, const sba_covariance_request *user,
                          CovarianceRequest *req) {
  if (!user || user->size < offsetof(sba_covariance_request, unscaled))
    return "req is NULL or not initialised by sba_covariance_request_init";
  // Each field added after ptcov is read only from a request that is large enough to hold it.
  const auto holds = [user](size_t offset, size_t size) { return user->size >= offset + size; };
  req->unscaled = holds(offsetof(sba_covariance_request, unscaled), sizeof user->unscaled) && user->unscaled != 0;
  if (holds(offsetof(sba_covariance_request, point_damping), sizeof user->point_damping))
    req->point_damping = user->point_damping;
  if (!(req->point_damping >= 0.0 && req->point_damping <= DBL_MAX))
    return "req->point_damping must be finite and >= 0";
  req->ncams = user->ncams;
  req->cams = user->cams;
  req->camcov = user->camcov;
  req->npts = user->npts;
  req->pts = user->pts;
  req->ptcov = user->ptcov;
  if (req->ncams < 0 || req->npts < 0) return "req->ncams and req->npts must be >= 0";
  if (req->ncams > 0 && (!req->cams || !req->camcov))
    return "req->cams and req->camcov must be given for ncams > 0";
  if (req->npts > 0 && (!req->pts || !req->ptcov))
    return "req->pts and req->ptcov must be given for npts > 0";
  for (int q = 0; q < req->ncams; ++q)
    if (req->cams[q] < 0 || req->cams[q] >= a.m)
      return "req->cams[" + std::to_string(q) + "] is not a camera index";
  for (int q = 0; q < req->npts; ++q)
    if (req->pts[q] < 0 || req->pts[q] >= a.n)
      return "req->pts[" + std::to_string(q) + "] is not a point index";
  return {};
}

}  // namespace

int run_driver(const DriverArgs &a) {
  const sba_ext_options ext = read_ext(a.ext);
  const Logger log = make_logger(a, ext);
  Summary sum;
  int ret = SBA_ERROR;
  const bool finished = catch_all(log, a.name, [&] {
    const Environment env = read_environment();
    Options opt;
    Layout lay;
    const auto no_extra_check = [] { return std::string(); };
    if (!validate_and_lay_out(a, ext, env, log, no_extra_check, &opt, &lay)) return;
    if (!choose_solver(a, lay, log, &opt)) return;
    const std::unique_ptr<Model> model = make_model(lay, a.callbacks, opt.parallel_callbacks);
    // itmax == 0: check the Jacobian; the solve below then only scores p (info[0] == info[1]).
    if (a.itmax == 0) {
      if (!model->has_jacobian())
        log.report("%s: itmax == 0 asks for a Jacobian check, but no analytic Jacobian was "
                   "given: nothing to check",
                   a.name);
      else
        check_jacobian(lay, *model, a.p, log);
      if (opt.priors.any()) PriorTerms(opt.priors, lay).check_jacobians(a.p, log);
    }
    const bool ok = solve(lay, *model, a.p, a.x, a.covx, opt, log, sum);
    count_as_1_6(a, lay, sum);
    write_result(ext, opt, sum);
    if (ok) ret = sum.iterations;
  });
  if (!finished) sum.ok = false;
  sum.to_info(a.info);
  return ret;
}

int run_covariance(const DriverArgs &a, sba_covariance_request *user) {
  const sba_ext_options ext = read_ext(a.ext);
  const Logger log = make_logger(a, ext);
  int ret = SBA_ERROR;
  catch_all(log, a.name, [&] {
    const Environment env = read_environment();
    Options opt;
    Layout lay;
    CovarianceRequest req;
    const auto request_check = [&] { return check_request(a, user, &req); };
    if (!validate_and_lay_out(a, ext, env, log, request_check, &opt, &lay)) return;
    const std::unique_ptr<Model> model = make_model(lay, a.callbacks, opt.parallel_callbacks);
    if (!covariance(lay, *model, a.p, a.x, a.covx, opt, log, req)) return;
    user->sigma2 = req.sigma2;
    user->rank = req.rank;
    user->nfree = req.nfree;
    ret = 0;
  });
  return ret;
}

}  // namespace sba
