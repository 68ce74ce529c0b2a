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

// info[6] values. 1..7 are sba 1.6's; the rest are ours and documented in the README.
enum StopReason : int {
  kStopNone = 0,         // no iteration ran: bad arguments, invalid covariance, no memory
  kStopGradient = 1,     // ||J^T e||_inf <= eps1
  kStopStep = 2,         // ||dp||^2 <= eps2^2 ||p||^2
  kStopItmax = 3,        // itmax iterations
  kStopReduction = 4,    // relative RMS error reduction < eps4
  kStopError = 5,        // ||e||^2 <= eps3^2
  kStopDamping = 6,      // damping could not grow any more: too many failed attempts
  kStopNonFinite = 7,    // f(p) or the Jacobian has a NaN or Inf
  kStopSingular = 8,     // the augmented system is almost singular
  kStopUser = 9,         // the progress callback asked to stop
};

struct Summary {
  // err0, err: the cost minimized (the robust cost with a loss); sq_err0, sq_err: the plain
  // sum of squared (covariance-weighted) residuals.
  double err0 = 0, err = 0, grad_inf = 0, dp2 = 0, mu_ratio = 0;
  double sq_err0 = 0, sq_err = 0;
  i64 outliers = 0;  // projections beyond the loss scale at the end
  int iterations = 0;
  int reason = kStopNone;
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

// The stop-4 test after an accepted step: e and en are the cost before and after it.
bool reduction_stalled(double e, double en, double eps4);

}  // namespace sba

#endif
