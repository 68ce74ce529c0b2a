/* SPDX-License-Identifier: BSD-3-Clause */
// A camera's pose both ways: X_c = R X + t (R row-major, world to camera) has its centre at
// C = -R^T t, and t = -R C. Formats that store the centre (NVM) and the PLY files of the
// programs share these; the camera models share the derivative of R X by a left increment.
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

// Columns col..col+2 of the 2 x cnp A: H d(R X)/dw for H 2x3 (d x / d X_c), where a change dw
// of the rotation's parameters turns R into exp([G dw]x) R to first order. Then d(R X)/dw =
// -[R X]x G: each row h of H becomes (R X x h) G, G made once per camera for all its points,
// fewer operations per projection than differentiating the rotation's own parameters.
// T is double, or a vector of doubles that carries several projections side by side.
template <class T>
inline void rotation_columns(const T H[6], const T RX[3], const T G[9], int cnp, int col, T *A) {
  for (int r = 0; r < 2; ++r) {
    const T *h = H + r * 3;
    const T k[3] = {RX[1] * h[2] - RX[2] * h[1], RX[2] * h[0] - RX[0] * h[2], RX[0] * h[1] - RX[1] * h[0]};
    for (int c = 0; c < 3; ++c) A[r * cnp + col + c] = k[0] * G[c] + k[1] * G[3 + c] + k[2] * G[6 + c];
  }
}

}  // namespace sbacameras

#endif  // SBA_LIB_CAMERAS_CAMERA_POSE_H
