/* SPDX-License-Identifier: BSD-3-Clause */
// The one Levenberg-Marquardt core behind the six 1.6 drivers: its entry point and its summary
// (its options: options.h).
#ifndef SBA_SRC_LM_H
#define SBA_SRC_LM_H

#include <functional>
#include <memory>

#include "layout.h"
#include "log.h"
#include "model.h"
#include "options.h"

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

struct Summary {
  // err0, err: the cost minimized (the robust cost with a loss, plus the priors' with
  // priors); sq_err0, sq_err: the projections' plain sum of squared (covariance-weighted)
  // residuals.
  double err0 = 0, err = 0, grad_inf = 0, dp2 = 0, mu_ratio = 0;
  double sq_err0 = 0, sq_err = 0;
  // err0 and err in two parts: the projections' cost and the priors' (0 without priors).
  double proj_err0 = 0, proj_err = 0, prior_err0 = 0, prior_err = 0;
  i64 outliers = 0;  // projections beyond the loss scale at the end
  int iterations = 0;
  StopReason reason = kStopNone;
  i64 nfev = 0, njev = 0, nlinsys = 0;
  bool ok = false;
  bool moved = false;  // a step was accepted: p is no longer the caller's

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

}  // namespace sba

#endif
