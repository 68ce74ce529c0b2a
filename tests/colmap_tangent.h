/* SPDX-License-Identifier: BSD-3-Clause */
// COLMAP's tangent of a rotation as the tests of its covariances measure it (test_colmap_camera.cpp,
// test_colmap_problem.cpp): the increment between two poses' quaternions, for central differences.
#ifndef SBA_TESTS_COLMAP_TANGENT_H
#define SBA_TESTS_COLMAP_TANGENT_H

#include <array>
#include <cmath>

#include "cameras/euclidean.h"

namespace tangenttest {

// COLMAP's rotation increment delta between two unit quaternions: q = [cos|delta|,
// sin|delta| delta/|delta|] * q_hat, the increment taken with w >= 0.
inline std::array<double, 3> colmap_increment(const sbacameras::euclidean::Quaternion &q,
                                              const sbacameras::euclidean::Quaternion &q_hat) {
  namespace eu = sbacameras::euclidean;
  eu::Quaternion inc = eu::multiply(q, {q_hat.w, -q_hat.x, -q_hat.y, -q_hat.z});
  if (inc.w < 0) inc = {-inc.w, -inc.x, -inc.y, -inc.z};
  const double s = std::sqrt(inc.x * inc.x + inc.y * inc.y + inc.z * inc.z);
  const double k = s == 0 ? 1.0 : std::atan2(s, inc.w) / s;
  return {k * inc.x, k * inc.y, k * inc.z};
}

}  // namespace tangenttest

#endif  // SBA_TESTS_COLMAP_TANGENT_H
