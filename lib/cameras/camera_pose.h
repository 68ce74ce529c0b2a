/* SPDX-License-Identifier: BSD-3-Clause */
// A camera's pose both ways: X_c = R X + t (R row-major, world to camera) has its centre at
// C = -R^T t, and t = -R C. Formats that store the centre (NVM) and the PLY files of the
// programs share these.
#ifndef SBA_LIB_CAMERAS_CAMERA_POSE_H
#define SBA_LIB_CAMERAS_CAMERA_POSE_H

#include <array>

namespace sbacameras {

inline std::array<double, 3> camera_centre(const double R[9], const double t[3]) {
  std::array<double, 3> c;
  // 0 - x rather than -x: a camera at the origin is written 0, not -0.
  for (int k = 0; k < 3; ++k) c[k] = 0.0 - (R[k] * t[0] + R[3 + k] * t[1] + R[6 + k] * t[2]);
  return c;
}

inline void camera_translation(const double R[9], const std::array<double, 3> &c, double t[3]) {
  for (int r = 0; r < 3; ++r) t[r] = -(R[3 * r] * c[0] + R[3 * r + 1] * c[1] + R[3 * r + 2] * c[2]);
}

}  // namespace sbacameras

#endif  // SBA_LIB_CAMERAS_CAMERA_POSE_H
