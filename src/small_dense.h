/* SPDX-License-Identifier: BSD-3-Clause */
// Small dense kernels on row-major square blocks (the per-camera and per-point blocks of
// the normal equations: 3x3 .. 16x16). Hand-written because LAPACK's per-call overhead
// dominates at these sizes.
#ifndef SBA_SRC_SMALL_DENSE_H
#define SBA_SRC_SMALL_DENSE_H

#include <cmath>
#include <utility>

namespace sba::small {

// Each function takes the order n at run time, or at compile time as N (then n is ignored),
// which lets the common 3x3 point blocks unroll completely.

// In-place Cholesky A = L L^T of an SPD n x n block; L ends in the lower triangle (the
// strict upper triangle is left untouched). False when A is not numerically SPD.
template <int N = 0>
inline bool chol(double *a, int n) {
  if (N) n = N;
  for (int j = 0; j < n; ++j) {
    double d = a[j * n + j];
    for (int k = 0; k < j; ++k) d -= a[j * n + k] * a[j * n + k];
    if (!(d > 0.0)) return false;  // also catches NaN
    d = std::sqrt(d);
    a[j * n + j] = d;
    const double inv = 1.0 / d;
    for (int i = j + 1; i < n; ++i) {
      double s = a[i * n + j];
      for (int k = 0; k < j; ++k) s -= a[i * n + k] * a[j * n + k];
      a[i * n + j] = s * inv;
    }
  }
  return true;
}

// Solve L L^T x = b in place, L from chol().
template <int N = 0>
inline void chol_solve(const double *l, double *b, int n) {
  if (N) n = N;
  for (int i = 0; i < n; ++i) {
    double s = b[i];
    for (int k = 0; k < i; ++k) s -= l[i * n + k] * b[k];
    b[i] = s / l[i * n + i];
  }
  for (int i = n - 1; i >= 0; --i) {
    double s = b[i];
    for (int k = i + 1; k < n; ++k) s -= l[k * n + i] * b[k];
    b[i] = s / l[i * n + i];
  }
}

// inv = A^-1 for SPD A (n x n). a's lower triangle is overwritten by L^-1 (L its Cholesky
// factor). False if not SPD. A^-1 = L^-T L^-1 with one reciprocal per diagonal
// entry and no solves: this runs for every point at every damping value, where the n^2
// divisions of n triangular solves were most of its cost. Each entry of the upper triangle is
// one sum, mirrored, so the block comes out exactly symmetric as the normal equations expect.
// The factorization is chol()'s, except that the diagonal keeps the reciprocals 1/L[j][j]
// that scale its columns (the factorization never reads the diagonal back), which L^-1 needs:
// the same values a second pass of divisions made.
template <int N = 0>
inline bool spd_inverse(double *a, double *inv, int n) {
  if (N) n = N;
  for (int j = 0; j < n; ++j) {
    double d = a[j * n + j];
    for (int k = 0; k < j; ++k) d -= a[j * n + k] * a[j * n + k];
    if (!(d > 0.0)) return false;  // also catches NaN
    const double r = 1.0 / std::sqrt(d);
    a[j * n + j] = r;
    for (int i = j + 1; i < n; ++i) {
      double s = a[i * n + j];
      for (int k = 0; k < j; ++k) s -= a[i * n + k] * a[j * n + k];
      a[i * n + j] = s * r;
    }
  }
  // L^-1 in place, column by column: X[i][j] = -(sum_{j<=k<i} L[i][k] X[k][j]) / L[i][i].
  // While column j is made, the columns right of it still hold L and the diagonal 1/L[i][i].
  for (int j = 0; j < n; ++j)
    for (int i = j + 1; i < n; ++i) {
      double s = a[i * n + j] * a[j * n + j];
      for (int k = j + 1; k < i; ++k) s += a[i * n + k] * a[k * n + j];
      a[i * n + j] = -s * a[i * n + i];
    }
  // A^-1 = X^T X.
  for (int i = 0; i < n; ++i)
    for (int j = i; j < n; ++j) {
      double s = 0.0;
      for (int k = j; k < n; ++k) s += a[k * n + i] * a[k * n + j];
      inv[i * n + j] = inv[j * n + i] = s;
    }
  return true;
}

// inv = A^-1 for a nonsingular symmetric A that need not be definite (n x n, read from its
// upper triangle, as LAPACK's symmetric routines read it); a is overwritten. Gauss-Jordan
// elimination with partial pivoting on [A | I]: for the small blocks it serves, where
// spd_inverse has just refused A, it gives the one inverse there is as well as a
// Bunch-Kaufman factorization would. The result is made exactly symmetric from its upper
// triangle. False only when a pivot column is exactly zero (A singular) or the inverse
// overflows.
template <int N = 0>
inline bool sym_inverse(double *a, double *inv, int n) {
  if (N) n = N;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < i; ++j) a[i * n + j] = a[j * n + i];
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) inv[i * n + j] = i == j ? 1.0 : 0.0;
  for (int c = 0; c < n; ++c) {
    int piv = c;
    for (int r = c + 1; r < n; ++r)
      if (std::fabs(a[r * n + c]) > std::fabs(a[piv * n + c])) piv = r;
    if (!(a[piv * n + c] != 0.0) || !std::isfinite(a[piv * n + c])) return false;
    if (piv != c)
      for (int k = 0; k < n; ++k) {
        std::swap(a[c * n + k], a[piv * n + k]);
        std::swap(inv[c * n + k], inv[piv * n + k]);
      }
    const double r = 1.0 / a[c * n + c];
    for (int k = 0; k < n; ++k) {
      a[c * n + k] *= r;
      inv[c * n + k] *= r;
    }
    for (int q = 0; q < n; ++q) {
      if (q == c) continue;
      const double f = a[q * n + c];
      if (f == 0.0) continue;
      for (int k = 0; k < n; ++k) {
        a[q * n + k] -= f * a[c * n + k];
        inv[q * n + k] -= f * inv[c * n + k];
      }
    }
  }
  for (int i = 0; i < n; ++i)
    for (int j = i; j < n; ++j) {
      if (!std::isfinite(inv[i * n + j])) return false;
      inv[j * n + i] = inv[i * n + j];
    }
  return true;
}

// Upper-triangular B with B^T B = A^-1 for SPD A (n x n); the weighting of the paper's
// covariance-aware cost. a and tmp are work blocks (a is destroyed). False if not SPD.
inline bool cholinv_upper(double *a, double *b, double *tmp, int n) {
  if (!spd_inverse(a, tmp, n)) return false;
  // A^-1 = U^T U: U^T is the lower Cholesky factor of A^-1.
  if (!chol(tmp, n)) return false;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) b[i * n + j] = (j >= i) ? tmp[j * n + i] : 0.0;
  return true;
}

}  // namespace sba::small

#endif
