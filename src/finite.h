/* SPDX-License-Identifier: BSD-3-Clause */
// The library's one test for NaN and Inf in an array of doubles, and where the first one is.
#ifndef SBA_SRC_FINITE_H
#define SBA_SRC_FINITE_H

#include <cmath>
#include <cstdint>

namespace sba {

// x - x is 0 for every finite x and NaN for Inf and NaN, and a NaN stays in a sum: eight
// independent sums over the array vectorize, where a loop returning at the first non-finite
// value does not (this runs on every residual vector and step of a solve).
inline bool all_finite(const double *v, std::int64_t len) {
  double acc[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  std::int64_t k = 0;
  for (; k + 8 <= len; k += 8)
    for (int q = 0; q < 8; ++q) acc[q] += v[k + q] - v[k + q];
  for (; k < len; ++k) acc[0] += v[k] - v[k];
  double s = 0.0;
  for (double x : acc) s += x;
  return s == s;
}

// Index of the first NaN or Inf of v, or -1: for messages that name the entry.
inline std::int64_t first_nonfinite(const double *v, std::int64_t len) {
  if (all_finite(v, len)) return -1;
  for (std::int64_t k = 0; k < len; ++k)
    if (!std::isfinite(v[k])) return k;
  return -1;
}

}  // namespace sba

#endif
