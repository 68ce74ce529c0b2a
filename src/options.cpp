// SPDX-License-Identifier: BSD-3-Clause
#include "options.h"

#include <cmath>

namespace sba {

bool Options::is_valid(std::string *error) const {
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
  return true;
}

}  // namespace sba
