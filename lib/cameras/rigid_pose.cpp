// SPDX-License-Identifier: BSD-3-Clause
#include "cameras/rigid_pose.h"

#include "cameras/euclidean.h"

namespace sbacameras {

namespace {

euclidean::Quaternion rotation(const std::array<double, 4> &q) {
  return euclidean::normalized_rotation({q[0], q[1], q[2], q[3]});
}

}  // namespace

RigidPose compose(const RigidPose &a, const RigidPose &b) {
  const euclidean::Quaternion qa = rotation(a.q);
  double R[9];
  euclidean::rotation_matrix(qa, R);
  const euclidean::Quaternion q = euclidean::multiply(qa, rotation(b.q));
  RigidPose p;
  p.q = {q.w, q.x, q.y, q.z};
  for (int r = 0; r < 3; ++r) p.t[r] = R[3 * r] * b.t[0] + R[3 * r + 1] * b.t[1] + R[3 * r + 2] * b.t[2] + a.t[r];
  return p;
}

RigidPose between(const RigidPose &a, const RigidPose &b) {
  const euclidean::Quaternion qa = rotation(a.q);
  double R[9];
  euclidean::rotation_matrix(qa, R);
  const euclidean::Quaternion q = euclidean::multiply({qa.w, -qa.x, -qa.y, -qa.z}, rotation(b.q));
  RigidPose p;
  p.q = {q.w, q.x, q.y, q.z};
  const double d[3] = {b.t[0] - a.t[0], b.t[1] - a.t[1], b.t[2] - a.t[2]};
  for (int c = 0; c < 3; ++c) p.t[c] = R[c] * d[0] + R[3 + c] * d[1] + R[6 + c] * d[2];
  return p;
}

RigidPose inverse(const RigidPose &p) { return between(p, RigidPose{}); }

}  // namespace sbacameras
