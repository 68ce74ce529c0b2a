/* SPDX-License-Identifier: BSD-3-Clause */
// How the block columns of S are shared among the threads that assemble it. A cost model of
// the assembly, not a vector kernel: one translation unit, whatever the CPU build of the
// kernels that use it.
#ifndef SBA_SRC_COLUMN_SPLIT_H
#define SBA_SRC_COLUMN_SPLIT_H

#include <vector>

#include "layout.h"

namespace sba {

// threads + 1 boundaries in free-camera indices (0 first, the number of free cameras last):
// thread t assembles block columns [split[t], split[t + 1]) of S, and the ranges cost about
// the same in multiply-adds (see column_split.cpp).
std::vector<int> split_schur_columns(const Layout &lay, int threads);

}  // namespace sba

#endif
