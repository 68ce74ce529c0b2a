/* SPDX-License-Identifier: BSD-3-Clause */
// A rigid pose X_out = R(q) X_in + t, and the two operations on poses: composition and inverse.
// The one definition of them in the repository: COLMAP's poses (an image's from its frame's
// rig_from_world and its camera's sensor_from_rig) and the rig camera model's compose here.
#ifndef SBA_LIB_CAMERAS_RIGID_POSE_H
#define SBA_LIB_CAMERAS_RIGID_POSE_H

#include <array>

namespace sbacameras {

// The quaternion Hamilton's, qw first, as COLMAP writes it. It is taken as a rotation (scaled to
// unit norm) wherever it is used, so that a pose read from a file with a few digits is one.
struct RigidPose {
  std::array<double, 4> q{1, 0, 0, 0};
  std::array<double, 3> t{};
};

// a b, the pose that applies b and then a: q = q_a q_b, t = R_a t_b + t_a, with q_a and q_b
// normalized first. The product is not normalized again: it is a unit quaternion to rounding,
// and COLMAP composes so too, which keeps its poses' bits within reach (colmap_io.h).
RigidPose compose(const RigidPose &a, const RigidPose &b);

// a^-1 b, the pose that takes a to b (compose(a, between(a, b)) is b to rounding): q = q_a^* q_b,
// t = R_a^T (t_b - t_a), with q_a and q_b normalized first.
RigidPose between(const RigidPose &a, const RigidPose &b);

// p^-1 = between(p, identity): q^* and -R^T t.
RigidPose inverse(const RigidPose &p);

}  // namespace sbacameras

#endif  // SBA_LIB_CAMERAS_RIGID_POSE_H
