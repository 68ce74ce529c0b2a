/* SPDX-License-Identifier: BSD-3-Clause */
// The library's basic types, at the bottom of its layers (docs/architecture.md): what a file
// needs to count and index, without knowing the problem.
#ifndef SBA_SRC_TYPES_H
#define SBA_SRC_TYPES_H

#include <cstdint>

namespace sba {

// Counts and offsets that may exceed an int: projections times their sizes, vector lengths,
// the orders of the reduced camera system.
using i64 = std::int64_t;

}  // namespace sba

#endif
