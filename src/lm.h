/* SPDX-License-Identifier: BSD-3-Clause */
// The one Levenberg-Marquardt core behind the six 1.6 drivers, its options and summary, and
// what else works on the normal equations at a point: the covariance and the Jacobian check.
#ifndef SBA_SRC_LM_H
#define SBA_SRC_LM_H

#include <functional>
#include <memory>
#include <vector>

#include "layout.h"
#include "log.h"
#include "loss.h"
#include "model.h"
#include "strategy.h"

namespace sba {

// Why a solve stopped: info[6], with sba_ext.h's values (sba_stop_reason_text says each in
// words). 1..7 are sba 1.6's; the rest are ours.
enum StopReason : int {
  kStopNone = SBA_STOP_NONE,            // nothing ran: bad arguments, invalid covariance, no memory
  kStopGradient = SBA_STOP_GRADIENT,    // ||J^T e||_inf <= eps1
  kStopStep = SBA_STOP_STEP,            // ||dp||^2 <= eps2^2 ||p||^2
  kStopItmax = SBA_STOP_ITMAX,          // itmax iterations
  kStopReduction = SBA_STOP_REDUCTION,  // relative RMS error reduction < eps4
  kStopError = SBA_STOP_ERROR,          // ||e||^2 <= eps3^2
  kStopDamping = SBA_STOP_DAMPING,      // damping could not grow any more: too many failed attempts
  kStopNonFinite = SBA_STOP_NONFINITE,  // f(p) or the Jacobian has a NaN or Inf
  kStopSingular = SBA_STOP_SINGULAR,    // the augmented system is almost singular
  kStopUser = SBA_STOP_USER,            // the progress callback asked to stop
};

// How the damped normal equations are solved (see step_solver.h).
enum class LinSolver {
  Chol,        // dense S, Cholesky (sba 1.6's default): the library's own up to 2048 unknowns
  CholLapack,  // dense S, LAPACK's DPOTRF/DPOTRS at every size
  LDLt,        // dense S, unpivoted LDL^T
  BK,          // dense S, Bunch-Kaufman
  LU,          // dense S, LU
  QR,          // dense S, QR
  QRnoQ,       // dense S, QR without Q (R^T R x = S^T b)
  SVD,         // dense S, SVD
  CG,          // dense S, Jacobi-preconditioned conjugate gradients
  LdlAmd,      // no Schur complement: the whole system, AMD ordering + sparse LDL^T
  SparseChol,  // sparse S (cameras sharing points), CHOLMOD Cholesky
  IterativeSchur,  // S never formed: truncated CG on S x products, S's block diagonal as preconditioner
};

struct Options {
  LinSolver solver = LinSolver::Chol;
  StrategyKind strategy = StrategyKind::Sba;
  double tau = SBA_INIT_MU;
  double eps1 = SBA_STOP_THRESH, eps2 = SBA_STOP_THRESH, eps3 = SBA_STOP_THRESH, eps4 = 0.0;
  int itmax = 0;
  int nthreads = 1;
  bool auto_threads = false;  // nthreads is the hardware's, not the caller's: see fit_threads
  bool parallel_callbacks = false;  // the caller's callbacks may run concurrently
  bool avoid_shared_cores = false;  // workers may narrow their own CPU mask (parallel.cpp)
  Loss loss;  // robust loss on each projection's squared residual (none: least squares)
  // Called after every outer iteration; nonzero stops with kStopUser.
  int (*progress)(void *ctx, const sba_progress *state) = nullptr;
  void *progress_ctx = nullptr;
  // Polled by the covariance computation; nonzero abandons it (sba_ext_options.cancel).
  int (*cancel)(void *ctx) = nullptr;
  void *cancel_ctx = nullptr;
};

struct Summary {
  // err0, err: the cost minimized (the robust cost with a loss); sq_err0, sq_err: the plain
  // sum of squared (covariance-weighted) residuals.
  double err0 = 0, err = 0, grad_inf = 0, dp2 = 0, mu_ratio = 0;
  double sq_err0 = 0, sq_err = 0;
  i64 outliers = 0;  // projections beyond the loss scale at the end
  int iterations = 0;
  StopReason reason = kStopNone;
  i64 nfev = 0, njev = 0, nlinsys = 0;
  bool ok = false;

  void to_info(double *info) const;
};

class StepSolver;
// Given the linear solver a solve makes, the one it is to use: for the tests, which wrap it
// to see what it is handed.
using SolverWrap = std::function<std::unique_ptr<StepSolver>(std::unique_ptr<StepSolver>)>;

// Runs LM on p (updated in place with the last accepted estimate). x: measurements;
// covx: null or per-measurement covariances. Returns false on failure (summary.ok too).
bool solve(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
           const Options &opt, const Logger &log, Summary &sum, const SolverWrap &wrap = nullptr);

class Kernels;

// The normal equations at p, without iterating: for the covariance of the solution.
struct Linearization {
  std::vector<double> jac, U, V, ea, eb;  // as in an LM iteration (weighted, reweighted)
  double sq_err = 0;                      // squared error of the (re)weighted residual
};
bool linearize(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
               const Options &opt, const Logger &log, ThreadPool &pool, const Kernels &kernels,
               Linearization *out);

// What sba_motstr_covariance* computes (see sba_ext.h), with validated indices.
struct CovarianceRequest {
  int ncams = 0;
  const int *cams = nullptr;
  double *camcov = nullptr;
  int npts = 0;
  const int *pts = nullptr;
  double *ptcov = nullptr;
  double sigma2 = 0;
  int rank = 0, nfree = 0;
};
bool covariance(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
                const Options &opt, const Logger &log, CovarianceRequest &req);

// The itmax == 0 check of an analytic Jacobian against central differences. Reports every
// suspicious entry and a one-line verdict through log. Returns the number of suspicious rows.
i64 check_jacobian(const Layout &lay, Model &model, double *p, const Logger &log);

}  // namespace sba

#endif
