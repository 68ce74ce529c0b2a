/* SPDX-License-Identifier: BSD-3-Clause */
// The block kernels' implementation, compiled twice: by kernels.cpp for any x86-64 (and other
// targets), and by kernels_avx2.cpp with AVX2 and FMA enabled, each into its own namespace
// SBA_KERNELS_NS. make_kernels picks the build the CPU can run.
#ifndef SBA_KERNELS_NS
#error "define SBA_KERNELS_NS before including kernels_impl.h"
#endif

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <type_traits>
#include <vector>
#ifdef __AVX__
#include <immintrin.h>
#endif

#include "column_split.h"
#include "kernels.h"
#include "madd.h"
#include "small_dense.h"

namespace sba {
namespace SBA_KERNELS_NS {
namespace {

// y[0..n) += s * x[0..n): the innermost step of every kernel below, over a contiguous row so
// that it vectorizes; N > 0 fixes n at compile time.
template <int N>
inline __attribute__((always_inline)) void axpy(int n, double s, const double *__restrict x,
                                                double *__restrict y) {
  if constexpr (N > 0) {
#pragma GCC unroll 16
    for (int c = 0; c < N; ++c) y[c] += s * x[c];
  } else {
    for (int c = 0; c < n; ++c) y[c] += s * x[c];
  }
}

// y[0..n) = s * x[0..n).
template <int N>
inline __attribute__((always_inline)) void scale_row(int n, double s, const double *__restrict x,
                                                     double *__restrict y) {
  if constexpr (N > 0) {
#pragma GCC unroll 16
    for (int c = 0; c < N; ++c) y[c] = s * x[c];
  } else {
    for (int c = 0; c < n; ++c) y[c] = s * x[c];
  }
}

// The rows of S_jk that the pairs of camera j update: a held parameter's Jacobian column is
// zero, so each of its terms Y_ij W_ik^T is a zero, which only the sign of a zero entry
// would notice; its row of S keeps U_j + mu D_j's. Bit a for row a; rows past the mask's
// width are always updated.
using RowMask = std::uint64_t;
inline __attribute__((always_inline)) bool updates(RowMask rows, int a) { return a >= 64 || (rows >> a & 1); }

// Every camera's RowMask: all rows, less those of its held parameters.
inline std::vector<RowMask> row_masks(const Layout &lay) {
  std::vector<RowMask> rows(size_t(std::max(lay.m, 0)), ~RowMask(0));
  if (lay.cams.any_held())
    for (int j = lay.mcon; j < lay.m; ++j)
      for (const int *c = lay.cams.held_begin(j); c != lay.cams.held_end(j); ++c)
        if (*c < 64) rows[size_t(j)] &= ~(RowMask(1) << *c);
  return rows;
}

#if defined(__AVX2__) && defined(__FMA__)
// A row of N doubles in registers: N / 4 vectors of four, then one of two and one scalar as
// N's remainder needs. Each operation rounds every entry as the scalar expression beside it,
// so code written with rows gives the bits of the same loops written entry by entry as the
// optimizing compiler builds them, a * b + c contracted to one fused operation, and the same
// bits at any optimization level. The compiler's own vectorization of those loops, with 9- or
// 11-wide rows, falls back to scalar code or shuffles each value out of a vector.
template <int N>
struct Row {
  static constexpr int V4 = N / 4, R2 = N % 4 >= 2, R1 = N % 2;
  __m256d v[V4 > 0 ? V4 : 1];
  __m128d h;
  double s;

  // k0 in the operations below: the vectors of four before the k0-th are left out (left zero
  // by load), for rows of which only the entries from 4 k0 on are wanted.
  static inline __attribute__((always_inline)) Row load(const double *x, int k0 = 0) {
    Row r{};
#pragma GCC unroll 4
    for (int k = k0; k < V4; ++k) r.v[k] = _mm256_loadu_pd(x + 4 * k);
    if constexpr (R2) r.h = _mm_loadu_pd(x + 4 * V4);
    if constexpr (R1) r.s = x[N - 1];
    return r;
  }
  inline __attribute__((always_inline)) void store(double *x, int k0 = 0) const {
#pragma GCC unroll 4
    for (int k = k0; k < V4; ++k) _mm256_storeu_pd(x + 4 * k, v[k]);
    if constexpr (R2) _mm_storeu_pd(x + 4 * V4, h);
    if constexpr (R1) x[N - 1] = s;
  }
  // a * y[c]
  static inline __attribute__((always_inline)) Row mul(double a, const Row &y, int k0 = 0) {
    Row r{};
    const __m256d b = _mm256_set1_pd(a);
#pragma GCC unroll 4
    for (int k = k0; k < V4; ++k) r.v[k] = _mm256_mul_pd(b, y.v[k]);
    if constexpr (R2) r.h = _mm_mul_pd(_mm256_castpd256_pd128(b), y.h);
    if constexpr (R1) r.s = a * y.s;
    return r;
  }
  // x[c] = fma(a, y[c], x[c])
  inline __attribute__((always_inline)) void fmadd(double a, const Row &y, int k0 = 0) {
    const __m256d b = _mm256_set1_pd(a);
#pragma GCC unroll 4
    for (int k = k0; k < V4; ++k) v[k] = _mm256_fmadd_pd(b, y.v[k], v[k]);
    if constexpr (R2) h = _mm_fmadd_pd(_mm256_castpd256_pd128(b), y.h, h);
    if constexpr (R1) s = __builtin_fma(a, y.s, s);
  }
  // x[c] + y[c]
  inline __attribute__((always_inline)) void add(const Row &y, int k0 = 0) {
#pragma GCC unroll 4
    for (int k = k0; k < V4; ++k) v[k] = _mm256_add_pd(v[k], y.v[k]);
    if constexpr (R2) h = _mm_add_pd(h, y.h);
    if constexpr (R1) s = s + y.s;
  }
  // x[c] = fma(-a, y[c], x[c]), which is x[c] - a * y[c] contracted
  inline __attribute__((always_inline)) void fnmadd(double a, const Row &y, int k0 = 0) {
    const __m256d b = _mm256_set1_pd(a);
#pragma GCC unroll 4
    for (int k = k0; k < V4; ++k) v[k] = _mm256_fnmadd_pd(b, y.v[k], v[k]);
    if constexpr (R2) h = _mm_fnmadd_pd(_mm256_castpd256_pd128(b), y.h, h);
    if constexpr (R1) s = __builtin_fma(-a, y.s, s);
  }
};

// S_jk -= Y_ij W_ik^T with W_ik^T's rows already in registers (w), row by row of S_jk as
// pair_update below.
template <int N, int D>
inline __attribute__((always_inline)) void pair_rows(const Row<N> *w, const double *Yt, double *S, i64 ld,
                                                     RowMask rows) {
#pragma GCC unroll 16
  for (int a = 0; a < N; ++a) {
    if (!updates(rows, a)) continue;
    Row<N> acc = Row<N>::load(S + a * ld);
#pragma GCC unroll 4
    for (int d = 0; d < D; ++d) acc.fnmadd(Yt[d * N + a], w[d]);
    acc.store(S + a * ld);
  }
}

// pair_rows for a diagonal block S_kk, whose strict lower triangle nothing reads: each row
// leaves out the vectors of four that lie wholly left of the diagonal. The entries it updates
// get pair_rows's operations, so the upper triangle has pair_rows's bits.
template <int N, int D>
inline __attribute__((always_inline)) void pair_rows_upper(const Row<N> *w, const double *Yt, double *S, i64 ld,
                                                           RowMask rows) {
#pragma GCC unroll 16
  for (int a = 0; a < N; ++a) {
    if (!updates(rows, a)) continue;
    Row<N> acc = Row<N>::load(S + a * ld, a / 4);
#pragma GCC unroll 4
    for (int d = 0; d < D; ++d) acc.fnmadd(Yt[d * N + a], w[d], a / 4);
    acc.store(S + a * ld, a / 4);
  }
}
#endif

// S_jk -= Y_ij W_ik^T for one pair of a track, with Y and W given transposed (pnp x n): row a
// of S_jk loses sum_d Y^T[d][a] W^T[d][.]. W^T is loaded into locals once and every row is
// accumulated in a local array, so the compiler sees no aliasing and keeps them in vector
// registers.
template <int N, int D>
inline __attribute__((always_inline)) void pair_update(int n, int pn, const double *Yt,
                                                       const double *Wt, double *S, i64 ld, RowMask rows) {
#if defined(__AVX2__) && defined(__FMA__)
  if constexpr (N > 0 && D > 0) {
    Row<N> w[D];
#pragma GCC unroll 4
    for (int d = 0; d < D; ++d) w[d] = Row<N>::load(Wt + d * N);
    pair_rows<N, D>(w, Yt, S, ld, rows);
    return;
  }
#endif
  if constexpr (N > 0 && D > 0) {
    double w[D][N];
#pragma GCC unroll 4
    for (int d = 0; d < D; ++d)
#pragma GCC unroll 16
      for (int c = 0; c < N; ++c) w[d][c] = Wt[d * N + c];
#pragma GCC unroll 16
    for (int a = 0; a < N; ++a) {
      if (!updates(rows, a)) continue;
      double acc[N];
      double *row = S + a * ld;
#pragma GCC unroll 16
      for (int c = 0; c < N; ++c) acc[c] = row[c];
#pragma GCC unroll 4
      for (int d = 0; d < D; ++d) {
        const double y = Yt[d * N + a];
#pragma GCC unroll 16
        for (int c = 0; c < N; ++c) acc[c] -= y * w[d][c];
      }
#pragma GCC unroll 16
      for (int c = 0; c < N; ++c) row[c] = acc[c];
    }
  } else {
    for (int a = 0; a < n; ++a) {
      if (!updates(rows, a)) continue;
      for (int d = 0; d < pn; ++d) {
        const double y = Yt[d * n + a];
        for (int c = 0; c < n; ++c) S[a * ld + c] -= y * Wt[d * n + c];
      }
    }
  }
}

// S_jk -= Y_ij W_ik^T for the pairs of one track that end at one entry (camera k): the track's
// first `count` entries, entry q's Y^T at Yt + q * stride and its block row of S at
// S + (cols[q] - mcon) * rowstride; the last of them is the entry itself, the diagonal block.
// Each entry of S gets pair_update's operations in pair_update's order, so the bits are the
// same. With AVX2, W_ik^T stays in registers for the whole column (written through S, the
// compiler would reload it for every pair), and the diagonal block is updated in its upper
// triangle only (pair_rows_upper): with tracks of a few images, many of the pairs.
template <int N, int D>
inline __attribute__((always_inline)) void column_pairs(int n, int pn, const double *Yt, int stride, int count,
                                                        const int *cols, int mcon, const double *Wt, double *S,
                                                        i64 rowstride, i64 ld, const RowMask *rows) {
#if defined(__AVX2__) && defined(__FMA__)
  if constexpr (N > 0 && D > 0) {
    Row<N> w[D];
#pragma GCC unroll 4
    for (int d = 0; d < D; ++d) w[d] = Row<N>::load(Wt + d * N);
    for (int q = 0; q + 1 < count; ++q)
      pair_rows<N, D>(w, Yt + i64(q) * stride, S + i64(cols[q] - mcon) * rowstride, ld, rows[cols[q]]);
    if (count > 0) {
      const int q = count - 1;
      pair_rows_upper<N, D>(w, Yt + i64(q) * stride, S + i64(cols[q] - mcon) * rowstride, ld, rows[cols[q]]);
    }
    return;
  }
#endif
  for (int q = 0; q < count; ++q)
    pair_update<N, D>(n, pn, Yt + i64(q) * stride, Wt, S + i64(cols[q] - mcon) * rowstride, ld, rows[cols[q]]);
}

#if defined(__AVX2__) && defined(__FMA__)
// Blocks one wider than a multiple of four (9 wide: BAL's cameras and COLMAP's common ones)
// are stored split in the assembly's packed copy: a block's first N - 1 columns as rows, its
// last column after them (at + N (N - 1)) as one vector. Row by row, that column took a scalar
// operation for each row and term, a third of a 9-wide row's operations for a ninth of its
// entries; as a vector it takes a row's. Where two or three columns are left over, a row
// already holds two of them in one vector, and splitting them off gained nothing
// (block_kernels_benchmark's AssembleS on 54cams and 54camsvarK).
constexpr bool kSplitBlocks = true;

// column_pairs for such blocks. Every entry gets the fused operations pair_rows gives it, in
// the same order, so the bits are the same. The last column of a held row (left out of the
// rows by the mask) is updated with the others: the row's Y^T entries are zero, as its A_ij
// column is, and the +0 its entries hold stays +0.
template <int N, int D>
inline __attribute__((always_inline)) void column_pairs_split(const double *Yt, int stride, int count, const int *cols,
                                                              int mcon, const double *Wt, double *S, i64 rowstride,
                                                              const RowMask *rows) {
  constexpr int L = N - 1, T = N * L;
  static_assert(L % 4 == 0 && L > 0, "rows of whole vectors and one column left over");
  Row<L> w[D];
  double wl[D];
#pragma GCC unroll 4
  for (int d = 0; d < D; ++d) w[d] = Row<L>::load(Wt + d * N), wl[d] = Wt[d * N + L];
  for (int q = 0; q < count; ++q) {
    const double *Y = Yt + i64(q) * stride;
    double *B = S + i64(cols[q] - mcon) * rowstride;
    const RowMask mask = rows[cols[q]];
    const bool diagonal = q == count - 1;  // its strict lower triangle is never read
#pragma GCC unroll 16
    for (int a = 0; a < N; ++a) {
      if (!updates(mask, a)) continue;
      const int k0 = diagonal ? a / 4 : 0;
      Row<L> acc = Row<L>::load(B + a * L, k0);
#pragma GCC unroll 4
      for (int d = 0; d < D; ++d) acc.fnmadd(Y[d * N + a], w[d], k0);
      acc.store(B + a * L, k0);
    }
    Row<N> last = Row<N>::load(B + T);
#pragma GCC unroll 4
    for (int d = 0; d < D; ++d) last.fnmadd(wl[d], Row<N>::load(Y + d * N));
    last.store(B + T);
  }
}
#else
constexpr bool kSplitBlocks = false;
template <int N, int D>  // never called: kSplitBlocks is false
void column_pairs_split(const double *, int, int, const int *, int, const double *, double *, i64, const RowMask *);
#endif

// One projection's W_ij^T = B^T A and Y_ij^T = V*_i^-1 W_ij^T (pnp x cnp each; A is mnp x cnp,
// B mnp x pnp, Vi pnp x pnp, all row-major). Every sum starts from its first term. With the
// sizes fixed, both products are built in locals (with AVX2, rows of registers) and stored
// once: written through the scratch arrays, the compiler cannot rule out aliasing and falls
// back to scalar code.
template <int M, int N, int D>
inline __attribute__((always_inline)) void track_products(int mn, int n, int pn, const double *A,
                                                          const double *B, const double *Vi,
                                                          double *__restrict Wt, double *__restrict Yt) {
#if defined(__AVX2__) && defined(__FMA__)
  if constexpr (M > 0 && N > 0 && D > 0) {
    Row<N> a[M], w[D], y[D];
#pragma GCC unroll 4
    for (int r = 0; r < M; ++r) a[r] = Row<N>::load(A + r * N);
#pragma GCC unroll 4
    for (int d = 0; d < D; ++d) {
      w[d] = Row<N>::mul(B[d], a[0]);
#pragma GCC unroll 4
      for (int r = 1; r < M; ++r) w[d].fmadd(B[r * D + d], a[r]);
      w[d].store(Wt + d * N);
    }
#pragma GCC unroll 4
    for (int d = 0; d < D; ++d) {
      y[d] = Row<N>::mul(Vi[d * D], w[0]);
#pragma GCC unroll 4
      for (int e = 1; e < D; ++e) y[d].fmadd(Vi[d * D + e], w[e]);
      y[d].store(Yt + d * N);
    }
    return;
  }
#endif
  if constexpr (M > 0 && N > 0 && D > 0) {
    double w[D][N], y[D][N];
#pragma GCC unroll 4
    for (int d = 0; d < D; ++d) {
#pragma GCC unroll 16
      for (int c = 0; c < N; ++c) w[d][c] = B[d] * A[c];
#pragma GCC unroll 4
      for (int r = 1; r < M; ++r)
#pragma GCC unroll 16
        for (int c = 0; c < N; ++c) w[d][c] = madd(B[r * D + d], A[r * N + c], w[d][c]);
    }
#pragma GCC unroll 4
    for (int d = 0; d < D; ++d) {
#pragma GCC unroll 16
      for (int c = 0; c < N; ++c) y[d][c] = Vi[d * D] * w[0][c];
#pragma GCC unroll 4
      for (int e = 1; e < D; ++e)
#pragma GCC unroll 16
        for (int c = 0; c < N; ++c) y[d][c] = madd(Vi[d * D + e], w[e][c], y[d][c]);
    }
#pragma GCC unroll 4
    for (int d = 0; d < D; ++d)
#pragma GCC unroll 16
      for (int c = 0; c < N; ++c) Wt[d * N + c] = w[d][c], Yt[d * N + c] = y[d][c];
  } else {
    for (int d = 0; d < pn; ++d) {
      scale_row<0>(n, B[d], A, Wt + d * n);
      for (int r = 1; r < mn; ++r) axpy<0>(n, B[r * pn + d], A + r * n, Wt + d * n);
    }
    for (int d = 0; d < pn; ++d) {
      scale_row<0>(n, Vi[d * pn], Wt, Yt + d * n);
      for (int e = 1; e < pn; ++e) axpy<0>(n, Vi[d * pn + e], Wt + e * n, Yt + d * n);
    }
  }
}

// rhs_k -= Y_ij e_b,i (Yt pnp x cnp): accumulated in locals for the same reason.
template <int N, int D>
inline __attribute__((always_inline)) void rhs_update(int n, int pn, const double *Yt, const double *eb,
                                                      double *__restrict rhs) {
  if constexpr (N > 0 && D > 0) {
    double r[N];
#pragma GCC unroll 16
    for (int c = 0; c < N; ++c) r[c] = rhs[c];
#pragma GCC unroll 4
    for (int d = 0; d < D; ++d)
#pragma GCC unroll 16
      for (int c = 0; c < N; ++c) r[c] += -eb[d] * Yt[d * N + c];
#pragma GCC unroll 16
    for (int c = 0; c < N; ++c) rhs[c] = r[c];
  } else {
    for (int d = 0; d < pn; ++d) axpy<0>(n, -eb[d], Yt + d * n, rhs);
  }
}

// G's strict lower triangle set from its upper one (G n x n, row-major).
template <int N>
inline void mirror_lower(int n, double *G) {
  const int nn = N > 0 ? N : n;
  for (int a = 1; a < nn; ++a)
    for (int c = 0; c < a; ++c) G[a * nn + c] = G[c * nn + a];
}

// G += X^T X and g += X^T e for one projection's mnp x n block X (row-major): the
// contribution of one measurement to U_j, e_a,j (X = A_ij) or to V_i, e_b,i (X = B_ij).
// Without the gradient (Grad false) e and g are not read: the gradient of single-precision
// blocks is made in double before they are rounded (lm_core.cpp). G[a][c] and G[c][a] get the
// same products in the same order; with Upper, the AVX2 rows may leave out entries left of the
// diagonal, and the caller copies the upper triangle down once G is complete (mirror_lower),
// which gives the same bits.
template <int M, int N, bool Grad = true, bool Upper = false>
inline __attribute__((always_inline)) void gram_update(int mn, int n, const double *X,
                                                       const double *e, double *G, double *g) {
#if defined(__AVX2__) && defined(__FMA__)
  if constexpr (M == 2 && N > 0) {
    // As below; the compiler contracts s0 x0 + s1 x1 to fma(s0, x0, s1 x1).
    const Row<N> x0 = Row<N>::load(X), x1 = Row<N>::load(X + N);
    if constexpr (Grad) {
      Row<N> t = Row<N>::mul(e[1], x1);
      t.fmadd(e[0], x0);
      Row<N> acc = Row<N>::load(g);
      acc.add(t);
      acc.store(g);
    }
#pragma GCC unroll 16
    for (int a = 0; a < N; ++a) {
      const int k0 = Upper ? a / 4 : 0;
      Row<N> t = Row<N>::mul(X[N + a], x1, k0);
      t.fmadd(X[a], x0, k0);
      Row<N> acc = Row<N>::load(G + a * N, k0);
      acc.add(t, k0);
      acc.store(G + a * N, k0);
    }
    return;
  }
#endif
  if constexpr (M == 2 && N > 0) {
    // Both rows of a 2-D projection in one pass: each entry of G is loaded and stored once.
    double x0[N], x1[N];
#pragma GCC unroll 16
    for (int c = 0; c < N; ++c) x0[c] = X[c], x1[c] = X[N + c];
    if constexpr (Grad) {
#pragma GCC unroll 16
      for (int c = 0; c < N; ++c) g[c] += e[0] * x0[c] + e[1] * x1[c];
    }
#pragma GCC unroll 16
    for (int a = 0; a < N; ++a) {
      const double s0 = x0[a], s1 = x1[a];
      double *row = G + a * N;
#pragma GCC unroll 16
      for (int c = 0; c < N; ++c) row[c] += s0 * x0[c] + s1 * x1[c];
    }
  } else {
    for (int r = 0; r < mn; ++r) {
      const double *x = X + r * n;
      if constexpr (Grad)
        for (int c = 0; c < n; ++c) g[c] += e[r] * x[c];
      for (int a = 0; a < n; ++a)
        for (int c = 0; c < n; ++c) G[a * n + c] += x[a] * x[c];
    }
  }
}

// Four lanes of doubles: four points' 3x3 blocks side by side, entry by entry.
typedef double lanes4 __attribute__((vector_size(32)));
typedef long long mask4 __attribute__((vector_size(32)));

// Lanes by reference: a 32-byte vector passed by value has a different ABI with and without
// AVX, which GCC warns of in the portable build.
inline __attribute__((always_inline)) void lanes_sqrt(lanes4 &x) {
#ifdef __AVX__
  x = lanes4(_mm256_sqrt_pd(__m256d(x)));
#else
  for (int l = 0; l < 4; ++l) x[l] = std::sqrt(x[l]);
#endif
}

// small::spd_inverse<3> on four SPD blocks at once, one per lane (a: 9 entries row-major,
// overwritten; inv: the inverses). The same operations in the same order as the scalar
// function, so each lane's result is what that function gives for its block, whatever the
// other lanes hold: a point's inverse does not depend on which points share its batch. The
// square roots and divisions, most of a 3x3 inverse's time, then go four at a time.
// ok: per lane all ones if the block is positive definite, else 0 (that lane's inv is junk).
inline __attribute__((always_inline)) void spd_inverse3_lanes(lanes4 *a, lanes4 *inv, mask4 &ok) {
  constexpr int n = 3;
  ok = mask4{-1, -1, -1, -1};
  for (int j = 0; j < n; ++j) {
    lanes4 d = a[j * n + j];
    for (int k = 0; k < j; ++k) d -= a[j * n + k] * a[j * n + k];
    ok &= d > 0.0;
    lanes_sqrt(d);
    const lanes4 r = 1.0 / d;
    a[j * n + j] = r;
    for (int i = j + 1; i < n; ++i) {
      lanes4 s = a[i * n + j];
      for (int k = 0; k < j; ++k) s -= a[i * n + k] * a[j * n + k];
      a[i * n + j] = s * r;
    }
  }
  for (int j = 0; j < n; ++j)
    for (int i = j + 1; i < n; ++i) {
      lanes4 s = a[i * n + j] * a[j * n + j];
      for (int k = j + 1; k < i; ++k) s += a[i * n + k] * a[k * n + j];
      a[i * n + j] = -s * a[i * n + i];
    }
  for (int i = 0; i < n; ++i)
    for (int j = i; j < n; ++j) {
      lanes4 s = {0.0, 0.0, 0.0, 0.0};
      for (int k = j; k < n; ++k) s += a[k * n + i] * a[k * n + j];
      inv[i * n + j] = inv[j * n + i] = s;
    }
}

// Block sizes as template arguments (0: take the run-time value), so that the loops of the
// common sizes are fully unrolled and vectorized. Blocks that the Schur assembly multiplies
// are kept transposed (pnp x cnp) so that every inner loop runs along a cnp-long row.
template <int M, int C, int P>
class KernelsT final : public Kernels {
 public:
  KernelsT(const Layout &lay, int threads, i64 max_packed)
      : lay_(lay), max_packed_(max_packed), rows_(row_masks(lay)) {
    int maxtrack = 0;
    for (int i = 0; i < lay.n; ++i) maxtrack = std::max(maxtrack, lay.rowptr[i + 1] - lay.rowptr[i]);
    scratch_.resize(size_t(std::max(threads, 1)));
    for (Scratch &s : scratch_) {
      s.Wt.resize(size_t(maxtrack) * size_t(cnp()) * size_t(pnp()) + 1);
      s.Yt.resize(s.Wt.size());
      s.blk.resize(size_t(std::max(cnp(), pnp())) + size_t(mnp()));
      s.wide.resize(size_t(lay.jblk()));
      s.damped.resize(size_t(kBatch) * size_t(pnp()) * size_t(pnp()));
      s.inv.resize(s.damped.size());
    }
    const int T = std::max(threads, 1);
    split_ = split_schur_columns(lay, T);
    cameras_ = split_cameras_by_projections(lay, T);
    points_ = split_points_by_projections(lay, lay.ncon, T);
    all_points_ = split_points_by_projections(lay, 0, T);
    // U_j and e_a,j of a thread's cameras are accumulated here, then copied out: where two
    // threads' ranges meet, the blocks of the last camera of one and the first of the
    // other share cache lines.
    if (T > 1 && cnp() > 0)
      for (int t = 0; t < T; ++t) {
        const i64 count = cameras_[size_t(t) + 1] - cameras_[size_t(t)];
        scratch_[size_t(t)].gram.resize(size_t(count * (cnp() * cnp() + cnp()) + 7));
      }
  }

  int mnp() const { return M ? M : lay_.mnp; }
  int cnp() const { return C ? C : lay_.cnp; }
  int pnp() const { return P ? P : lay_.pnp; }

  void normal_equations(ThreadPool &pool, const double *jac, const double *e, double *U, double *V,
                        double *ea, double *eb) const override {
    gram(pool, jac, e, U, V, ea, eb);
  }
  void held_normal_equations(ThreadPool &pool, double *jac, const double *e, double *U, double *V, double *ea,
                             double *eb) const override {
    gram(pool, jac, e, U, V, ea, eb, jac);
  }
  void normal_matrices(ThreadPool &pool, const float *jac, double *U, double *V) const override {
    gram(pool, jac, nullptr, U, V, nullptr, nullptr);
  }

  bool invert_damped_V(ThreadPool &pool, const double *V, double mu, double *Vinv) const override {
    return pool.all_ranges(lay_.n - lay_.ncon, [&](int t, i64 b, i64 end) {
      return invert_points(V, mu, Vinv, b + lay_.ncon, end + lay_.ncon, scratch_[size_t(t)]);
    });
  }

  void damped_inverse_diagonals(ThreadPool &pool, const double *V, double mu, double *diag) const override {
    pool.for_range_t(lay_.n - lay_.ncon, [&](int t, i64 b, i64 end) {
      inverse_diagonals(V, mu, diag, b + lay_.ncon, end + lay_.ncon, scratch_[size_t(t)]);
    });
  }

  bool assemble(ThreadPool &pool, const NormalEquations &ne, const double *Vinv, double mu,
                const BlockMap &S, double *rhs) const override {
    return pool.all_members(
        [&](int t) {
          return assemble_columns(split_[size_t(t)], split_[size_t(t) + 1], ne, Vinv, mu, S, rhs,
                                  scratch_[size_t(t)]);
        },
        split_.size() == 2);
  }

  void scale_jacobian(ThreadPool &pool, const double *s, JacobianBlocks jac) const override {
    over(pool, all_points_, [&](int, i64 b, i64 e) {
      if (jac.jac32)
        scale_points(s, jac.jac32, b, e);
      else
        scale_points(s, jac.jac, b, e);
    });
  }

  void back_substitute(ThreadPool &pool, const NormalEquations &ne, const double *Vinv, double mu,
                       double *dp) const override {
    over(pool, points_, [&](int t, i64 b, i64 end) {
      if (ne.jac32)
        back_substitute_points(ne.jac32, ne, Vinv, mu, dp, b, end, scratch_[size_t(t)]);
      else
        back_substitute_points(ne.jac, ne, Vinv, mu, dp, b, end, scratch_[size_t(t)]);
    });
  }

 private:
  // Points whose (V_i + mu I)^-1 are made together (see point_inverses).
  static constexpr int kBatch = 8;

  struct Scratch {
    std::vector<double> Wt, Yt, blk;  // one track's W_ij^T and Y_ij^T; small vectors
    std::vector<double> wide;         // one projection's blocks widened (run-time sizes)
    std::vector<double> damped, inv;  // kBatch blocks V_i + mu I (overwritten), their inverses
    std::vector<double> gram;         // this thread's U_j and e_a,j, with several threads
    std::vector<double> packed;       // its block columns of a dense S (packed_offset)
  };

  // The work of one thread's range, out of line. Called from the pool's std::function, an
  // inlined job would see the block sizes only as values captured by reference, and its
  // fixed-size loops would fall back to run-time bounds, which costs more than a second thread
  // gains (block_kernels_benchmark's BackSubstitute/*/1 against /2 is the measurement); and
  // one copy of the code for every thread count keeps the compiler's choice of fused
  // multiply-adds, and so the bits, the same for all of them.

  // U_j and e_a,j for the cameras [j0, j1): the projections are walked in memory order
  // (point by point), taking those of these cameras, so the Jacobian is streamed rather than
  // visited camera by camera, and every U_j still adds its terms in ascending point order,
  // the same for any number of threads. U_j[a][c] and U_j[c][a] get the same products in
  // the same order, so U_j is exactly symmetric: only its upper triangle is accumulated, and
  // copied down at the end. Blocks in single precision give U_j alone (normal_matrices).
  // held: null, or jac itself, whose blocks get their held columns zeroed first. The points
  // [i0, i1) get their V_i and e_b,i in the same walk, as gram_points makes them: the walk
  // reads their blocks anyway, and a pass of their own would read them again.
  template <class J>
  __attribute__((noinline)) void gram_cameras(const J *jac, const double *e, double *U, double *ea,
                                              int j0, int j1, Scratch *sc, double *wide, double *held,
                                              double *V, double *eb, i64 i0, i64 i1) const {
    constexpr bool grad = std::is_same_v<J, double>;
    const Layout &lay = lay_;
    const int mn = mnp(), cn = cnp(), pn = pnp(), jb = lay.jblk();
    const i64 nu = i64(j1 - j0) * cn * cn, nea = grad ? i64(j1 - j0) * cn : 0;
    double *Uo = U + i64(j0) * cn * cn, *eao = grad ? ea + i64(j0) * cn : nullptr;
    double *Ut = sc ? align_to_line(sc->gram.data()) : Uo;
    double *eat = sc ? Ut + nu : eao;
    std::fill(Ut, Ut + nu, 0.0);
    std::fill(eat, eat + nea, 0.0);
    const int *colidx = lay.colidx.data(), *rowptr = lay.rowptr.data();
    double wl[M * C > 0 ? M * C : 1], wp[M * P > 0 ? M * P : 1];
    double *wa = M * C > 0 ? wl : wide, *wb = M * P > 0 ? wp : wide;
    for (i64 i = 0; i < lay.n; ++i) {
      const bool point = i >= i0 && i < i1;
      double *__restrict Vi = point ? V + i * pn * pn : nullptr;
      double *__restrict ebi = point && grad ? eb + i * pn : nullptr;
      if (point) {
        std::fill(Vi, Vi + pn * pn, 0.0);
        if constexpr (grad) std::fill(ebi, ebi + pn, 0.0);
      }
      for (i64 k = rowptr[i]; k < rowptr[i + 1]; ++k) {
        const int j = colidx[k];
        if (j >= j0 && j < j1) {
          if (held) lay.cams.zero_held(j, mn, held + k * jb);
          const double *A = widened<M * C>(jac + k * jb, mn * cn, wa);
          gram_update<M, C, grad, true>(mn, cn, A, grad ? e + k * mn : nullptr, Ut + i64(j - j0) * cn * cn,
                                        grad ? eat + i64(j - j0) * cn : nullptr);
        }
        if (point) {
          const double *B = widened<M * P>(jac + k * jb + mn * cn, mn * pn, wb);
          gram_update<M, P, grad>(mn, pn, B, grad ? e + k * mn : nullptr, Vi, ebi);
        }
      }
    }
    for (int j = j0; j < j1; ++j) mirror_lower<C>(cn, Ut + i64(j - j0) * cn * cn);
    if (sc) {
      std::copy(Ut, Ut + nu, Uo);
      std::copy(eat, eat + nea, eao);
    }
  }

  // The projections of the points [i0, i1) scaled (scale_jacobian), out of line for the
  // fixed sizes' loops.
  template <class J>
  __attribute__((noinline)) void scale_points(const double *s, J *jac, i64 i0, i64 i1) const {
    const Layout &lay = lay_;
    const int mn = mnp(), cn = cnp(), pn = pnp(), jb = lay.jblk();
    for (i64 i = i0; i < i1; ++i) {
      const double *si = s + lay.b_off(int(i));
      for (int k = lay.rowptr[size_t(i)]; k < lay.rowptr[size_t(i) + 1]; ++k) {
        J *A = jac + i64(k) * jb, *B = A + mn * cn;
        const double *sj = s + lay.a_off(lay.colidx[size_t(k)]);
        for (int r = 0; r < mn; ++r) {
          for (int c = 0; c < cn; ++c) A[r * cn + c] *= sj[c];
          for (int c = 0; c < pn; ++c) B[r * pn + c] *= si[c];
        }
      }
    }
  }

  // V_i and e_b,i for the points [i0, i1) (V_i alone from single-precision blocks).
  template <class J>
  __attribute__((noinline)) void gram_points(const J *jac, const double *e, double *V, double *eb,
                                             i64 i0, i64 i1, double *wide) const {
    constexpr bool grad = std::is_same_v<J, double>;
    const Layout &lay = lay_;
    const int mn = mnp(), cn = cnp(), pn = pnp(), jb = lay.jblk();
    const int *rowptr = lay.rowptr.data();
    double wl[M * P > 0 ? M * P : 1];
    if (M * P > 0) wide = wl;
    for (i64 i = i0; i < i1; ++i) {
      double *__restrict Vi = V + i * pn * pn, *__restrict ebi = grad ? eb + i * pn : nullptr;
      std::fill(Vi, Vi + pn * pn, 0.0);
      if constexpr (grad) std::fill(ebi, ebi + pn, 0.0);
      for (int k = rowptr[i]; k < rowptr[i + 1]; ++k) {
        const double *B = widened<M * P>(jac + i64(k) * jb + mn * cn, mn * pn, wide);
        gram_update<M, P, grad>(mn, pn, B, grad ? e + i64(k) * mn : nullptr, Vi, ebi);
      }
    }
  }

  // normal_equations of blocks stored as J; held: as gram_cameras's.
  template <class J>
  void gram(ThreadPool &pool, const J *jac, const double *e, double *U, double *V, double *ea,
            double *eb, double *held = nullptr) const {
    // One job for both parts: a thread with cameras forms its points' blocks in the walk
    // over the projections that its cameras take; one without, in a pass over its points.
    const int T = pool.size();
    auto part = [&](int t) {
      const i64 c0 = cameras_[size_t(t)], c1 = cameras_[size_t(t) + 1];
      i64 p0 = points_[size_t(t)], p1 = points_[size_t(t) + 1];
      if (pnp() == 0) p0 = p1 = 0;
      if (cnp() > 0 && c0 < c1) {
        gram_cameras(jac, e, U, ea, int(c0), int(c1), T > 1 ? &scratch_[size_t(t)] : nullptr,
                     scratch_[size_t(t)].wide.data(), held, V, eb, p0, p1);
        return;
      }
      if (p0 < p1) gram_points(jac, e, V, eb, p0, p1, scratch_[size_t(t)].wide.data());
    };
    if (T == 1)
      part(0);
    else
      pool.run(part);
  }

  // fn(t, begin, end) for each range of split (cameras_, points_ or all_points_), concurrently.
  template <class Fn>
  static void over(ThreadPool &pool, const std::vector<i64> &split, Fn fn) {
    const auto one = [&](int t) {
      const i64 b = split[size_t(t)], e = split[size_t(t) + 1];
      if (b < e) fn(t, b, e);
    };
    if (pool.size() == 1)
      one(0);
    else
      pool.run(one);
  }

  // (V_i + mu I)^-1 for the points [i0, i1); false at the first singular one.
  __attribute__((noinline)) bool invert_points(const double *V, double mu, double *Vinv, i64 i0, i64 i1,
                                               Scratch &sc) const {
    const int pn = pnp();
    for (i64 i = i0; i < i1; ++i)
      if (!damped_inverse(V, mu, nullptr, i, sc.damped.data(), Vinv + i * pn * pn)) return false;
    return true;
  }

  // The diagonals of (V_i + mu I)^-1 for the points [i0, i1), through point_inverses (the
  // same inverses as the assembly's), kBatch at a time.
  __attribute__((noinline)) void inverse_diagonals(const double *V, double mu, double *diag, i64 i0, i64 i1,
                                                   Scratch &sc) const {
    const int pn = pnp();
    const double *Vib[kBatch];
    int pts[kBatch];
    for (i64 i = i0; i < i1; i += kBatch) {
      const int count = int(std::min<i64>(i1 - i, kBatch));
      for (int b = 0; b < count; ++b) pts[b] = int(i) + b;
      point_inverses(nullptr, V, mu, nullptr, pts, count, sc, Vib);
      for (int b = 0; b < count; ++b)
        for (int a = 0; a < pn; ++a) diag[(i + b) * pn + a] = Vib[b] ? Vib[b][a * pn + a] : NAN;
    }
  }

  // Where the assembly writes dense S's block columns: block j of column k at
  // column(k) + j * rowstride, its rows ld apart; in S itself, or in the thread's packed copy.
  // A packed copy of blocks one wider than a multiple of four (kSplit) stores them split
  // (column_pairs_split): their first ld columns as rows, the last one at + tail.
  struct DenseColumns {
    double *base;
    i64 rowstride, ld;
    bool packed;
    int k0, cn;
    i64 tail;  // 0: not split
    // The blocks of a packed copy's columns k0 .. k - 1, each holding blocks 0 .. its own.
    static i64 blocks_before(int k0, int k) { return i64(k - k0) * (k0 + 1) + i64(k - k0) * (k - k0 - 1) / 2; }
    double *column(int k) const { return packed ? base + blocks_before(k0, k) * rowstride : base + i64(k) * cn; }
    // Entry (a, c) of the block at blk.
    double &entry(double *blk, int a, int c) const { return tail && c == ld ? blk[tail + a] : blk[a * ld + c]; }
  };
  static constexpr bool kSplit = kSplitBlocks && C > 4 && C % 4 == 1 && P > 0;

  // S's block columns [k0, k1) and their blocks of rhs before the points' terms: the diagonal
  // blocks U_k + mu D_k, the rest zero. A dense S is assembled in the thread's packed copy of
  // its block columns, blocks 0 .. k of column k one after the other, where S's upper
  // triangle fits in max_packed_ doubles. Updated in S itself, a block's rows lie S's row apart
  // and straddle twice the cache lines, and two threads' columns share the lines where they
  // meet.
  DenseColumns start_columns(int k0, int k1, const NormalEquations &ne, double mu, const BlockMap &S, double *rhs,
                             Scratch &sc) const {
    const Layout &lay = lay_;
    const int cn = cnp(), nc = lay.free_cams();
    const bool packed = !S.perm && i64(nc) * (nc + 1) / 2 * cn * cn <= max_packed_;
    DenseColumns out{S.base, i64(cn) * S.ld, S.ld, false, k0, cn, 0};
    if (packed) {
      sc.packed.assign(size_t(DenseColumns::blocks_before(k0, k1) * cn * cn), 0.0);
      const int rowlen = kSplit ? cn - 1 : cn;
      out = DenseColumns{sc.packed.data(), i64(cn) * cn, rowlen, true, k0, cn, kSplit ? i64(cn) * rowlen : 0};
    }
    if (!S.perm)  // dense S: block rows 0 .. k1 - 1 of these columns; packed, those below the
      for (i64 r = 0; r < i64(k1) * cn; ++r) {  // diagonal alone, the rest copied in at the end
        double *row = S.base + r * S.ld;
        const int kz = packed ? std::min(std::max(int(r / cn), k0), k1) : k1;
        std::fill(row + i64(k0) * cn, row + i64(kz) * cn, 0.0);
      }
    for (int k = k0; k < k1; ++k) {
      const BlockMap::Block blk =
          S.perm ? S.block(k, k) : BlockMap::Block{out.column(k) + k * out.rowstride, out.ld, false};
      double *Skk = blk.p;
      const i64 ld = blk.ld;
      const auto entry = [&](int a, int c) -> double & { return S.perm ? Skk[a * ld + c] : out.entry(Skk, a, c); };
      const double *Uk = ne.U + i64(k + lay.mcon) * cn * cn;
      for (int a = 0; a < cn; ++a) {
        for (int c = 0; c < cn; ++c) entry(a, c) = Uk[a * cn + c];
        entry(a, a) += ne.damping ? mu * ne.damping[lay.a_off(k + lay.mcon) + a] : mu;
      }
      const double *eak = ne.ea + i64(k + lay.mcon) * cn;
      for (int a = 0; a < cn; ++a) rhs[i64(k) * cn + a] = eak[a];
    }
    return out;
  }

  // The packed copy of block columns [k0, k1) into S.
  void finish_columns(int k0, int k1, const DenseColumns &dc, const BlockMap &S) const {
    if (!dc.packed) return;
    const int cn = cnp();
    for (int k = k0; k < k1; ++k)
      for (int j = 0; j <= k; ++j)
        for (int a = 0; a < cn; ++a) {
          // A row of a block, too short for a call to memmove to pay: its first ld entries as
          // they lie, and a split block's last one from the block's tail.
          const double *from = dc.column(k) + j * dc.rowstride;
          double *to = S.base + (i64(j) * cn + a) * S.ld + i64(k) * cn;
          for (int c = 0; c < dc.ld; ++c) to[c] = from[a * dc.ld + c];
          if (dc.tail) to[dc.ld] = from[dc.tail + a];
        }
  }

  // S's block columns [k0, k1) (free cameras) and their blocks of rhs, adding the points'
  // contributions in ascending point order; false if some V_i + mu I is singular.
  __attribute__((noinline)) bool assemble_columns(int k0, int k1, const NormalEquations &ne,
                                                  const double *Vinv, double mu, const BlockMap &S,
                                                  double *rhs, Scratch &sc) const {
    if (k0 >= k1) return true;
    const Layout &lay = lay_;
    const int cn = cnp(), pn = pnp(), cp = cn * pn;
    const DenseColumns dc = start_columns(k0, k1, ne, mu, S, rhs, sc);
    // The points whose tracks meet these columns, kBatch at a time: their inverses first.
    int pts[kBatch], fb[kBatch], lob[kBatch], hib[kBatch];
    const double *Vib[kBatch];
    for (int next = lay.ncon; next < lay.n;) {
      int nb = 0;
      for (; next < lay.n && nb < kBatch; ++next)
        if (track_in_columns(next, k0, k1, fb[nb], lob[nb], hib[nb])) pts[nb++] = next;
      point_inverses(Vinv, ne.V, mu, ne.damping, pts, nb, sc, Vib);
      for (int b = 0; b < nb; ++b) {
        const int i = pts[b], f = fb[b], lo = lob[b], hi = hib[b];
        if (!Vib[b]) return false;
        if (ne.jac32)
          products(ne.jac32, ne, i, f, lo, hi, Vib[b], sc, rhs);
        else
          products(ne.jac, ne, i, f, lo, hi, Vib[b], sc, rhs);
        for (int q2 = lo; q2 < hi; ++q2) {
          const int k = lay.colidx[q2] - lay.mcon;
          const double *Wt2 = sc.Wt.data() + (q2 - f) * cp;
          const double *Yt2 = sc.Yt.data() + (q2 - f) * cp;
          // S_jk -= Y_ij W_ik^T, row by row: S_jk[a][.] -= sum_d Y^T[d][a] W^T[d][.]; where
          // the map stores S_jk^T, S_jk^T -= Y_ik W_ij^T instead. The diagonal block is updated
          // whole, like the others (its strict lower triangle is never read), which keeps the
          // rows vectorized.
          if (!S.perm) {  // dense S: the hot loop of the default solver, without the map's lookups
            if constexpr (kSplit) {
              if (dc.tail) {
                column_pairs_split<C, P>(sc.Yt.data(), cp, q2 - f + 1, lay.colidx.data() + f, lay.mcon, Wt2,
                                      dc.column(k), dc.rowstride, rows_.data());
                continue;
              }
            }
            column_pairs<C, P>(cn, pn, sc.Yt.data(), cp, q2 - f + 1, lay.colidx.data() + f, lay.mcon, Wt2,
                               dc.column(k), dc.rowstride, dc.ld, rows_.data());
            continue;
          }
          for (int q1 = f; q1 <= q2; ++q1) {
            const double *Yt1 = sc.Yt.data() + (q1 - f) * cp;
            const double *Wt1 = sc.Wt.data() + (q1 - f) * cp;
            const BlockMap::Block Sjk = S.block(lay.colidx[q1] - lay.mcon, k);
            if (Sjk.transposed)
              pair_update<C, P>(cn, pn, Yt2, Wt1, Sjk.p, Sjk.ld, rows_[size_t(k + lay.mcon)]);
            else
              pair_update<C, P>(cn, pn, Yt1, Wt2, Sjk.p, Sjk.ld, rows_[size_t(lay.colidx[q1])]);
          }
        }
      }
    }
    finish_columns(k0, k1, dc, S);
    return true;
  }

  // Point i's W_ij^T and Y_ij^T for its track's entries [f, hi) into Wt and Yt (entry f's
  // first), and the terms of rhs of its entries [lo, hi).
  template <class J>
  void products(const J *jac, const NormalEquations &ne, int i, int f, int lo, int hi, const double *Vi,
                Scratch &sc, double *rhs) const {
    const Layout &lay = lay_;
    const int mn = mnp(), cn = cnp(), pn = pnp(), jb = lay.jblk(), cp = cn * pn;
    double *Wt = sc.Wt.data(), *Yt = sc.Yt.data();
    double wl[M > 0 ? M * (C + P) : 1];
    double *wide = M > 0 ? wl : sc.wide.data();
    for (int q = f; q < hi; ++q) {
      const double *A = widened<M * (C + P)>(jac + i64(q) * jb, jb, wide), *B = A + mn * cn;
      track_products<M, C, P>(mn, cn, pn, A, B, Vi, Wt + (q - f) * cp, Yt + (q - f) * cp);
    }
    const double *ebi = ne.eb + i64(i) * pn;
    for (int q = lo; q < hi; ++q)
      rhs_update<C, P>(cn, pn, Yt + (q - f) * cp, ebi, rhs + i64(lay.colidx[q] - lay.mcon) * cn);
  }

  // db_i = V*_i^-1 (e_b,i - sum_j W_ij^T da_j) for the points [i0, i1), every sum a chain
  // of fused multiply-adds. With the sizes fixed, t and u are locals that the compiler keeps
  // in registers; otherwise they live in the thread's scratch.
  template <class J>
  __attribute__((noinline)) void back_substitute_points(const J *jac, const NormalEquations &ne, const double *Vinv,
                                                        double mu, double *dp, i64 i0, i64 i1,
                                                        Scratch &sc) const {
    const Layout &lay = lay_;
    const int mn = mnp(), cn = cnp(), pn = pnp(), jb = lay.jblk();
    const int *rowptr = lay.rowptr.data(), *colidx = lay.colidx.data();
    double tl[P > 0 ? P : 1], ul[M > 0 ? M : 1];
    double *t = P > 0 ? tl : sc.blk.data(), *u = M > 0 ? ul : sc.blk.data() + pn;
    double wl[M > 0 ? M * (C + P) : 1];
    double *wide = M > 0 ? wl : sc.wide.data();
    const double *Vib[kBatch];
    int pts[kBatch];
    for (i64 i = i0; i < i1; ++i) {
      const int slot = int((i - i0) % kBatch);
      if (slot == 0) {
        const int count = int(std::min<i64>(i1 - i, kBatch));
        for (int b = 0; b < count; ++b) pts[b] = int(i) + b;
        point_inverses(Vinv, ne.V, mu, ne.damping, pts, count, sc, Vib);
      }
      for (int c = 0; c < pn; ++c) t[c] = ne.eb[i * pn + c];
      for (int k = rowptr[i]; k < rowptr[i + 1]; ++k) {
        const int j = colidx[k];
        if (j < lay.mcon) continue;
        const double *A = widened<M * (C + P)>(jac + i64(k) * jb, jb, wide), *B = A + mn * cn;
        const double *daj = dp + lay.a_off(j);
        // W^T da = B^T (A da): two thin products instead of forming W.
        for (int r = 0; r < mn; ++r) {
          double s = 0.0;
          for (int a = 0; a < cn; ++a) s = madd(A[r * cn + a], daj[a], s);
          u[r] = s;
        }
        for (int r = 0; r < mn; ++r)
          for (int c = 0; c < pn; ++c) t[c] = madd(-u[r], B[r * pn + c], t[c]);
      }
      double *dbi = dp + lay.b_off(int(i));
      const double *Vi = Vib[slot];
      if (!Vi) {
        std::fill(dbi, dbi + pn, NAN);
        continue;
      }
      for (int a = 0; a < pn; ++a) {
        double s = 0.0;
        for (int c = 0; c < pn; ++c) s = madd(Vi[a * pn + c], t[c], s);
        dbi[a] = s;
      }
    }
  }

  // (V_i + mu I)^-1 into inv (work: pnp^2 scratch); false if singular. The damped block is
  // positive definite but where sba 1.6's retries have left an indefinite diagonal on it
  // (strategy.cpp): Cholesky first, and where it refuses, the symmetric-indefinite inverse
  // that 1.6's Bunch-Kaufman gives.
  bool damped_inverse(const double *V, double mu, const double *damping, i64 i, double *work, double *inv) const {
    const int pn = pnp();
    const double *Vi = V + i * pn * pn;
    const auto damp = [&] {
      for (int a = 0; a < pn * pn; ++a) work[a] = Vi[a];
      if (damping)
        for (int a = 0; a < pn; ++a) work[a * pn + a] += mu * damping[lay_.b_off(int(i)) + a];
      else
        for (int a = 0; a < pn; ++a) work[a * pn + a] += mu;
    };
    damp();
    if (small::spd_inverse<P>(work, inv, pn)) return true;
    damp();
    return small::sym_inverse<P>(work, inv, pn);
  }

  // (V_i + mu I)^-1 of the points pts[0 .. count) (count <= kBatch) into out: from
  // Vinv, or made in sc (null where singular). Made together, their square
  // roots and divisions overlap (3x3 blocks: four to a vector); made as each point's turn
  // came, every point would wait for its own (kernels_benchmark's Solve1 shows the cost).
  // Inlined, with inverses3, into the loops of the assembly and the back-substitution that
  // call it for every batch of points.
  __attribute__((always_inline)) void point_inverses(const double *Vinv, const double *V, double mu,
                                                     const double *damping, const int *pts, int count, Scratch &sc,
                                                     const double **out) const {
    if constexpr (P == 3) {
      if (!Vinv) {
        for (int g = 0; g < count; g += 4)
          inverses3(V, mu, damping, pts + g, std::min(4, count - g), sc, g, out + g);
        return;
      }
    }
    const int pp = pnp() * pnp();
    for (int b = 0; b < count; ++b) {
      const i64 i = pts[b];
      if (Vinv) {
        out[b] = Vinv + i * pp;
        continue;
      }
      double *inv = sc.inv.data() + b * pp;
      out[b] = damped_inverse(V, mu, damping, i, sc.damped.data() + b * pp, inv) ? inv : nullptr;
    }
  }

  // (V_i + mu I)^-1 of up to four points pts[0 .. count) through spd_inverse3_lanes, into
  // sc.inv's slots from slot0 on. Missing lanes get the identity.
  __attribute__((always_inline)) void inverses3(const double *V, double mu, const double *damping, const int *pts,
                                                int count, Scratch &sc, int slot0, const double **out) const {
    lanes4 a[9], inv[9];
    for (int e = 0; e < 9; ++e)
      for (int l = 0; l < 4; ++l)
        a[e][l] = l < count ? V[i64(pts[l]) * 9 + e] : (e % 4 == 0 ? 1.0 : 0.0);
    if (damping)
      for (int e = 0; e < 9; e += 4)
        for (int l = 0; l < count; ++l) a[e][l] += mu * damping[lay_.b_off(pts[l]) + e / 4];
    else
      for (int e = 0; e < 9; e += 4)
        for (int l = 0; l < count; ++l) a[e][l] += mu;
    mask4 ok;
    spd_inverse3_lanes(a, inv, ok);
    for (int l = 0; l < count; ++l) {
      double *dst = sc.inv.data() + (slot0 + l) * 9;  // sc.inv: kBatch blocks
      if (ok[l]) {
        for (int e = 0; e < 9; ++e) dst[e] = inv[e][l];
        out[l] = dst;
      } else {  // not positive definite: damped_inverse's fallback, one block
        out[l] = damped_inverse(V, mu, damping, pts[l], sc.damped.data() + (slot0 + l) * 9, dst) ? dst : nullptr;
      }
    }
  }

  // Point i's track in block columns [k0, k1) of S: f the first entry of a free camera,
  // [lo, hi) the entries in the range; false if there are none.
  bool track_in_columns(int i, int k0, int k1, int &f, int &lo, int &hi) const {
    const Layout &lay = lay_;
    const int r1 = lay.rowptr[i + 1];
    f = lay.rowptr[i];  // fixed cameras come first
    while (f < r1 && lay.colidx[f] < lay.mcon) ++f;
    lo = f;
    while (lo < r1 && lay.colidx[lo] - lay.mcon < k0) ++lo;
    if (lo == r1 || lay.colidx[lo] - lay.mcon >= k1) return false;
    hi = lo;
    while (hi < r1 && lay.colidx[hi] - lay.mcon < k1) ++hi;
    return true;
  }

  const Layout &lay_;
  const i64 max_packed_;  // see start_columns
  std::vector<RowMask> rows_;  // row_masks: each camera's rows of S that its points update
  // threads + 1 boundaries each, for the pool of that size the kernels are made for (as
  // scratch_): the assembly's in free-camera indices; by projections, of the free cameras,
  // the free points and every point
  std::vector<int> split_;
  std::vector<i64> cameras_, points_, all_points_;
  mutable std::vector<Scratch> scratch_;
};

}  // namespace

std::unique_ptr<Kernels> make_kernels(const Layout &lay, int threads, i64 max_packed) {
  if (lay.mnp == 2 && lay.pnp == 3) {
    switch (lay.cnp) {
      case 6: return std::make_unique<KernelsT<2, 6, 3>>(lay, threads, max_packed);
      case 7: return std::make_unique<KernelsT<2, 7, 3>>(lay, threads, max_packed);
      case 9: return std::make_unique<KernelsT<2, 9, 3>>(lay, threads, max_packed);
      case 11: return std::make_unique<KernelsT<2, 11, 3>>(lay, threads, max_packed);
      case 16: return std::make_unique<KernelsT<2, 16, 3>>(lay, threads, max_packed);
      default: break;
    }
  }
  return std::make_unique<KernelsT<0, 0, 0>>(lay, threads, max_packed);
}

}  // namespace SBA_KERNELS_NS
}  // namespace sba
