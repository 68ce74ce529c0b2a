// SPDX-License-Identifier: BSD-3-Clause
#include "options.h"

#include <cmath>
#include <cstdio>

namespace sba {

namespace {

// The losses divide and multiply by scale^2; outside this range it overflows or underflows,
// and the solve would fail for a reason that blames x or stop at once.
std::string check_loss(const Loss &loss) {
  if (!loss.robust() || (loss.scale() >= kMinLossScale && loss.scale() <= kMaxLossScale)) return {};
  char buf[160];
  std::snprintf(buf, sizeof buf,
                "loss_scale must be positive and within [%.3g, %.3g], where its square and "
                "inverse square are normal numbers (got %g)",
                kMinLossScale, kMaxLossScale, loss.scale());
  return buf;
}

}  // namespace

std::string check_single_jacobian(const Options &opt, const Layout &lay, bool per_projection) {
  if (!opt.single_jacobian) return "";
  if (!per_projection)
    return "single_precision_jacobian needs the simple drivers' per-projection callbacks: an "
           "expert driver's fjac fills the whole Jacobian in double";
  if (!lay.cams.per_camera())
    return "single_precision_jacobian does not work with shared camera parameters (cam_group, "
           "cam_shared, cam_param_group)";
  if (opt.solver == LinSolver::LdlAmd) return "single_precision_jacobian does not work with ldl-amd";
  return "";
}

bool Options::is_valid(const Layout &lay, const double *p, std::string *error) const {
  if (itmax < 0) {
    *error = "itmax must be >= 0 (got " + std::to_string(itmax) + ")";
    return false;
  }
  const double opts[] = {tau, eps1, eps2, eps3, eps4};
  for (int k = 0; k < int(sizeof opts / sizeof opts[0]); ++k)
    if (!std::isfinite(opts[k])) {
      *error = "opts[" + std::to_string(k) + "] is not finite";
      return false;
    }
  // 1.6 takes |tau|; tau = 0 makes the initial damping 0, which no failed step can grow.
  if (tau == 0.0) {
    *error = "opts[0] (tau: the initial damping is |tau| * max diag(J^T J)) must be nonzero";
    return false;
  }
  *error = check_loss(loss);
  if (error->empty()) *error = check_camera_params(cams, lay, p);
  if (error->empty()) *error = check_priors(priors, lay, cams);
  return error->empty();
}

}  // namespace sba
