/* SPDX-License-Identifier: BSD-3-Clause */
// Vectors over the camera parameters and over the camera side's unknowns, through the
// Layout's CameraMap (camera_map.h): what the LM core, the strategies and the solvers do with
// shared unknowns without knowing more of them.
#ifndef SBA_SRC_UNKNOWNS_H
#define SBA_SRC_UNKNOWNS_H

#include <vector>

#include "layout.h"

namespace sba {

// The unknowns a solve of lay has: its free parameters less the held ones, a shared one
// counted once.
i64 count_unknowns(const Layout &lay);

// The shared parameters' copies in p set to the value of their first camera (the one of
// least index); returns the values they replaced, for restore_copies.
std::vector<double> tie_copies(const Layout &lay, double *p);
// p's copies as they were before tie_copies returned given.
void restore_copies(const Layout &lay, double *p, const std::vector<double> &given);

// The camera part of a vector over the camera parameters (m cnp entries, free cameras from
// mcon on) reduced to the unknowns (P^T x: each unknown the sum of its copies, in ascending
// camera order, held parameters left out), and an unknowns' vector expanded to the camera
// parameters (P x: every copy gets its unknown's value, a held parameter `held_value`,
// cameras below mcon left alone). For lay.cams.shared() only.
void to_unknowns(const Layout &lay, const double *x_cams, double *x_unknowns);
void to_cameras(const Layout &lay, const double *x_unknowns, double held_value, double *x_cams);

}  // namespace sba

#endif
