/* SPDX-License-Identifier: BSD-3-Clause */
// The library's own dense Cholesky factorization of S (the `chol` solver), compiled twice:
// by dense_chol.cpp for any x86-64 (and other targets), and by dense_chol_avx2.cpp with AVX2
// and FMA enabled, each into its own namespace SBA_DENSE_CHOL_NS. The factorization reaches
// it through own_dense_cholesky (dense_factorization.h), which picks the build the CPU runs.
//
// Why not LAPACK's DPOTRF: a threaded BLAS rounds differently with each thread count
// (OpenBLAS's DPOTRF changes its blocking), so the LM steps, and on the sba demo problems the
// number of iterations, changed with the BLAS's threads; and at the sizes of S where a dense
// factorization is the right choice (up to a few thousand unknowns), OpenBLAS's second
// thread gains nothing. This one computes every entry by the same operations as the
// unblocked right-looking algorithm (each entry loses its terms in ascending order, one
// fused multiply-add each where the CPU has FMA, then one multiplication by its pivot's
// reciprocal), however the work is blocked and split: the same bits for any thread count.
// S is row-major upper (as the assembly leaves it), which is LAPACK's column-major lower.
#ifndef SBA_DENSE_CHOL_NS
#error "define SBA_DENSE_CHOL_NS before including dense_chol_impl.h"
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#ifdef __AVX__
#include <immintrin.h>
#endif

#include "dense_factorization.h"
#include "madd.h"
#include "parallel.h"

namespace sba {
namespace SBA_DENSE_CHOL_NS {
namespace {

namespace chol {

// Rows per panel: the trailing update reads kPanel rows of U, which stay in the L2 cache.
constexpr int kPanel = 48;

// y[0..n) -= u * x[0..n), one rounding per entry (the scalar tail rounds as the lanes do).
inline __attribute__((always_inline)) void row_nmadd(i64 n, double u, const double *__restrict x,
                                                     double *__restrict y) {
  i64 j = 0;
#ifdef __FMA__
  const __m256d uu = _mm256_set1_pd(u);
  for (; j + 4 <= n; j += 4)
    _mm256_storeu_pd(y + j, _mm256_fnmadd_pd(uu, _mm256_loadu_pd(x + j), _mm256_loadu_pd(y + j)));
#endif
  for (; j < n; ++j) y[j] = madd(-u, x[j], y[j]);
}

// The lanes of the trailing update: four doubles with AVX, two (SSE2) without.
#ifdef __AVX__
constexpr int kW = 4;
typedef double lanes __attribute__((vector_size(32)));
typedef double lanes_u __attribute__((vector_size(32), aligned(8)));  // at any double's address
#else
constexpr int kW = 2;
typedef double lanes __attribute__((vector_size(16)));
typedef double lanes_u __attribute__((vector_size(16), aligned(8)));
#endif

// a - x * b in every lane, one rounding (as madd rounds a scalar).
inline __attribute__((always_inline)) lanes nmadd_lanes(double x, lanes b, lanes a) {
#ifdef __FMA__
  return lanes(_mm256_fnmadd_pd(_mm256_set1_pd(x), __m256d(b), __m256d(a)));
#else
  return a - x * b;
#endif
}

// Rows [i0, i0 + R) of the trailing matrix, columns [j, j + kW NV): S[i][c] -= S[p][i] S[p][c]
// for p in [p0, p1), in that order, in registers.
template <int R, int NV>
inline __attribute__((always_inline)) void tile(double *S, i64 ld, i64 p0, i64 p1, i64 i0, i64 j) {
  lanes acc[R][NV];
#pragma GCC unroll 8
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) acc[r][v] = *reinterpret_cast<const lanes_u *>(S + (i0 + r) * ld + j + kW * v);
  for (i64 p = p0; p < p1; ++p) {
    const double *up = S + p * ld;
    lanes b[NV];
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) b[v] = *reinterpret_cast<const lanes_u *>(up + j + kW * v);
#pragma GCC unroll 8
    for (int r = 0; r < R; ++r) {
      const double a = up[i0 + r];
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) acc[r][v] = nmadd_lanes(a, b[v], acc[r][v]);
    }
  }
#pragma GCC unroll 8
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) *reinterpret_cast<lanes_u *>(S + (i0 + r) * ld + j + kW * v) = acc[r][v];
}

// The trailing update by panel rows [p0, p1) of rows [i0, i0 + R), columns [max(i0, jlo),
// jhi), jlo a multiple of 4. The first tile starts at i0 rounded down to a multiple of 4:
// the few entries left of the diagonal that it also computes are in the unused lower
// triangle.
template <int R>
inline __attribute__((always_inline)) void update_rows(double *S, i64 ld, i64 p0, i64 p1, i64 i0,
                                                       i64 jlo, i64 jhi) {
  constexpr int kNV = kW == 4 ? 3 : 4;  // 12 accumulators with AVX, 16 (of 2) with SSE2
  i64 j = std::max(jlo, i0 - i0 % 4);
  for (; j + kW * kNV <= jhi; j += kW * kNV) tile<R, kNV>(S, ld, p0, p1, i0, j);
  for (; j + kW <= jhi; j += kW) tile<R, 1>(S, ld, p0, p1, i0, j);
  for (int r = 0; r < R; ++r)
    for (i64 c = j; c < jhi; ++c) {
      double s = S[(i0 + r) * ld + c];
      for (i64 p = p0; p < p1; ++p) s = madd(-S[p * ld + i0 + r], S[p * ld + c], s);
      S[(i0 + r) * ld + c] = s;
    }
}

// Rows [r0, r1) of the trailing matrix (up to column n, right-hand sides included) updated
// by panel rows [p0, p1). The columns go in blocks whose part of the panel (kPanel x kColumns
// doubles, 144 KB) stays in the L2 cache while every row passes over it.
__attribute__((noinline)) inline void trailing_rows(double *S, i64 ld, i64 n, i64 p0, i64 p1,
                                                    i64 r0, i64 r1) {
  constexpr i64 kColumns = 384;
  for (i64 jlo = r0 - r0 % kColumns; jlo < n; jlo += kColumns) {
    const i64 jhi = std::min(n, jlo + kColumns);
    i64 i = r0;
    for (; i + 4 <= r1 && i < jhi; i += 4) update_rows<4>(S, ld, p0, p1, i, jlo, jhi);
    for (; i < r1 && i < jhi; ++i) update_rows<1>(S, ld, p0, p1, i, jlo, jhi);
  }
}

// Panel rows [p0, p1), columns [j, j + kW NV): row q loses S[p][q] S[p][.] for p in [p0, q)
// in that order, then is scaled by its pivot's reciprocal; rows go two at a time (the second
// takes the first's term last), every entry in a register until it is final. The rows of
// the chunk above q are in L1, where a row-by-row update of whole panel rows would stream
// the panel through L2 once per row.
template <int NV>
inline __attribute__((always_inline)) void panel_chunk(double *S, i64 ld, i64 p0, i64 p1,
                                                       const double *inv, i64 j) {
  i64 q = p0;
  for (; q + 2 <= p1; q += 2) {
    double *u0 = S + q * ld + j, *u1 = u0 + ld;
    lanes a0[NV], a1[NV];
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) {
      a0[v] = *reinterpret_cast<const lanes_u *>(u0 + kW * v);
      a1[v] = *reinterpret_cast<const lanes_u *>(u1 + kW * v);
    }
    for (i64 p = p0; p < q; ++p) {
      const double *up = S + p * ld;
      const double x0 = up[q], x1 = up[q + 1];
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) {
        const lanes b = *reinterpret_cast<const lanes_u *>(up + j + kW * v);
        a0[v] = nmadd_lanes(x0, b, a0[v]);
        a1[v] = nmadd_lanes(x1, b, a1[v]);
      }
    }
    const double s0 = inv[q - p0], s1 = inv[q + 1 - p0], x = S[q * ld + q + 1];
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) {
      a0[v] *= s0;
      *reinterpret_cast<lanes_u *>(u0 + kW * v) = a0[v];
      *reinterpret_cast<lanes_u *>(u1 + kW * v) = nmadd_lanes(x, a0[v], a1[v]) * s1;
    }
  }
  for (; q < p1; ++q) {
    double *u0 = S + q * ld + j;
    lanes a0[NV];
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) a0[v] = *reinterpret_cast<const lanes_u *>(u0 + kW * v);
    for (i64 p = p0; p < q; ++p) {
      const double *up = S + p * ld;
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) a0[v] = nmadd_lanes(up[q], *reinterpret_cast<const lanes_u *>(up + j + kW * v), a0[v]);
    }
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) *reinterpret_cast<lanes_u *>(u0 + kW * v) = a0[v] * inv[q - p0];
  }
}

// Columns [c0, c1) of the panel rows [p0, p1), right of the panel's diagonal block (already
// factored; inv holds its pivots' reciprocals).
__attribute__((noinline)) inline void panel_columns(double *S, i64 ld, i64 p0, i64 p1,
                                                    const double *inv, i64 c0, i64 c1) {
  constexpr int kNV = 4;
  i64 j = c0;
  for (; j + kW * kNV <= c1; j += kW * kNV) panel_chunk<kNV>(S, ld, p0, p1, inv, j);
  for (; j + kW <= c1; j += kW) panel_chunk<1>(S, ld, p0, p1, inv, j);
  for (; j < c1; ++j)
    for (i64 q = p0; q < p1; ++q) {
      double s = S[q * ld + j];
      for (i64 p = p0; p < q; ++p) s = madd(-S[p * ld + q], S[p * ld + j], s);
      S[q * ld + j] = s * inv[q - p0];
    }
}

// The panel's diagonal block [p0, p1)^2: kPanel^3 / 6 multiply-adds; inv gets the pivots'
// reciprocals. False if a pivot is not positive.
inline bool diagonal_block(double *S, i64 ld, i64 p0, i64 p1, double *inv) {
  for (i64 p = p0; p < p1; ++p) {
    double *up = S + p * ld;
    const double d = up[p];
    if (!(d > 0.0) || !std::isfinite(d)) return false;
    const double r = std::sqrt(d), s = 1.0 / r;
    up[p] = r;
    inv[p - p0] = s;
    for (i64 c = p + 1; c < p1; ++c) up[c] *= s;
    for (i64 q = p + 1; q < p1; ++q) row_nmadd(p1 - q, up[q], up + q, S + q * ld + q);
  }
  return true;
}

// S = U^T U in place; false (S then undefined) if S is not numerically positive definite.
// Columns [n, ncols) of the rows hold right-hand sides b, which become U^-T b: they are
// updated as the columns of S are, so the forward substitution costs no pass of its own.
// With several threads, one pool job runs the whole factorization, its phases (the
// diagonal block on one thread, the panel's columns, the trailing rows) separated by
// barriers.
inline bool factor(ThreadPool &pool, double *S, i64 n, i64 ld, i64 ncols) {
  const int T = pool.size();
  double inv[kPanel];
  if (T == 1 || n < 128 || !pool.together()) {
    for (i64 p0 = 0; p0 < n; p0 += kPanel) {
      const i64 p1 = std::min(n, p0 + kPanel);
      if (!diagonal_block(S, ld, p0, p1, inv)) return false;
      panel_columns(S, ld, p0, p1, inv, p1, ncols);
      trailing_rows(S, ld, ncols, p0, p1, p1, n);
    }
    return true;
  }
  // Look-ahead: thread 0's trailing rows always start with the next panel's, which it updates
  // first and then factors that panel's diagonal block while the others finish their rows.
  // Two barriers per panel: after the diagonal block and the panel's columns, and after the
  // trailing update.
  SpinBarrier barrier(T);
  bool ok = true;  // written by thread 0 before a barrier, read by all after it
  double waiting = 0.0;  // the caller's (member T - 1's) time at the barriers
  const auto start = std::chrono::steady_clock::now();
  pool.run([&](int t) {
    auto sync = [&] { t == T - 1 ? barrier.wait(&waiting) : barrier.wait(); };
    if (t == 0) ok = diagonal_block(S, ld, 0, std::min<i64>(n, kPanel), inv);
    sync();
    if (!ok) return;
    for (i64 p0 = 0; p0 < n; p0 += kPanel) {
      const i64 p1 = std::min(n, p0 + kPanel), p2 = std::min(n, p1 + kPanel);
      const i64 w = n - p1, wc = ncols - p1;
      // The panel's columns split evenly (in whole cache lines), the trailing rows so that
      // every thread updates about the same number of entries (rows [p1, p1 + x) hold a
      // fraction 1 - (1 - x/w)^2 of them), thread 0's at least the next panel.
      const i64 c0 = p1 + (wc * t / T) / 8 * 8, c1 = t + 1 == T ? ncols : p1 + (wc * (t + 1) / T) / 8 * 8;
      if (c0 < c1) panel_columns(S, ld, p0, p1, inv, c0, c1);
      if (w == 0) return;
      sync();
      auto bound = [&](int k) -> i64 {
        if (k >= T) return n;
        const i64 x = p1 + i64(double(w) * (1.0 - std::sqrt(1.0 - double(k) / T))) / 4 * 4;
        return std::min(n, std::max(p2, x));
      };
      const i64 r0 = t == 0 ? p1 : bound(t), r1 = bound(t + 1);
      if (t == 0) {
        trailing_rows(S, ld, ncols, p0, p1, p1, p2);
        // inv is free again: every thread is past this panel's columns.
        ok = diagonal_block(S, ld, p1, p2, inv);
        if (p2 < r1) trailing_rows(S, ld, ncols, p0, p1, p2, r1);
      } else if (r0 < r1) {
        trailing_rows(S, ld, ncols, p0, p1, r0, r1);
      }
      sync();
      if (!ok) return;
    }
  });
  // A factorization that fails stops at its first bad pivot, before any phase's waits mean
  // anything.
  if (ok) pool.waited(waiting, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return ok;
}

}  // namespace chol

}  // namespace

// The dense Cholesky of this build, for own_dense_cholesky (dense_factorization.h).
bool dense_cholesky(ThreadPool &pool, double *S, i64 n, i64 ld, i64 nrhs) {
  return chol::factor(pool, S, n, ld, n + nrhs);
}

}  // namespace SBA_DENSE_CHOL_NS
}  // namespace sba
