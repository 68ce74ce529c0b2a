/* SPDX-License-Identifier: BSD-3-Clause */
// How the block columns of S are shared among the threads that assemble it, and the cameras
// and points among the threads of the passes over the projections. Cost models, not vector
// kernels: one translation unit, whatever the CPU build of the kernels that use them.
#ifndef SBA_SRC_COLUMN_SPLIT_H
#define SBA_SRC_COLUMN_SPLIT_H

#include <vector>

#include "layout.h"

namespace sba {

// threads + 1 boundaries in free-camera indices (0 first, the number of free cameras last):
// thread t assembles block columns [split[t], split[t + 1]) of S, and the ranges cost about
// the same in multiply-adds (see column_split.cpp).
std::vector<int> split_schur_columns(const Layout &lay, int threads);

// threads + 1 boundaries by projections, in the layout's own indices: of the free cameras
// (mcon first, m last) and of the points [first, n). Range t holds about a threads-th of
// their projections (evenly by count where they have none): a camera costs the projections
// it makes, a point its track, and BAL's vary by tens. The passes split this way compute each
// camera or point alone, so their bits do not depend on the boundaries.
std::vector<i64> split_cameras_by_projections(const Layout &lay, int threads);
std::vector<i64> split_points_by_projections(const Layout &lay, int first, int threads);

}  // namespace sba

#endif
