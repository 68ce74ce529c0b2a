/* SPDX-License-Identifier: BSD-3-Clause */
// The mapped assembly's hot loops (mapped_schur.h), compiled twice as the block kernels are
// (kernels_impl.h): by mapped_schur.cpp for any x86-64, and by mapped_schur_avx2.cpp with AVX2
// and FMA, each into its own namespace SBA_KERNELS_NS; MappedSchur picks the build the CPU
// runs.
#ifndef SBA_KERNELS_NS
#error "define SBA_KERNELS_NS before including mapped_schur_impl.h"
#endif

#include <algorithm>

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#endif

#include "mapped_schur.h"

namespace sba {
namespace SBA_KERNELS_NS {
namespace {

// out[a][c] -= sum_d Lt[d][a] Rt[d][c] for a < n1, c < n2 (Lt pnp x n1, Rt pnp x n2): one
// point's term of a block of S, row by row along contiguous rows. N1, N2, P > 0 fix the sizes
// at compile time for the blocks that dominate (poses of 6 against poses of 6, points of 3),
// whose loops then unroll into registers.
template <int N1, int N2, int P>
inline void pair_update_t(int n1, int n2, int pn, const double *__restrict Lt, const double *__restrict Rt,
                          double *__restrict out, i64 ld) {
  if constexpr (N1 > 0) n1 = N1;
  if constexpr (N2 > 0) n2 = N2;
  if constexpr (P > 0) pn = P;
  for (int a = 0; a < n1; ++a) {
    double *row = out + a * ld;
    for (int d = 0; d < pn; ++d) {
      const double z = Lt[d * n1 + a];
      const double *r = Rt + d * n2;
      for (int c = 0; c < n2; ++c) row[c] -= z * r[c];
    }
  }
}

#if defined(__AVX2__) && defined(__FMA__)
// Poses against poses, points of 3, in vector registers: what the loops above do to each
// entry (with FMA, one fused multiply-subtract per term, d ascending), four and two entries
// of a row at a time; the compiler leaves the unrolled loops scalar.
inline void pair_update_663(const double *__restrict Lt, const double *__restrict Rt, double *__restrict out,
                            i64 ld) {
  const __m256d r0 = _mm256_loadu_pd(Rt), r1 = _mm256_loadu_pd(Rt + 6), r2 = _mm256_loadu_pd(Rt + 12);
  const __m128d t0 = _mm_loadu_pd(Rt + 4), t1 = _mm_loadu_pd(Rt + 10), t2 = _mm_loadu_pd(Rt + 16);
  for (int a = 0; a < 6; ++a) {
    double *row = out + a * ld;
    const __m256d z0 = _mm256_broadcast_sd(Lt + a), z1 = _mm256_broadcast_sd(Lt + 6 + a),
                  z2 = _mm256_broadcast_sd(Lt + 12 + a);
    __m256d x = _mm256_loadu_pd(row);
    __m128d y = _mm_loadu_pd(row + 4);
    x = _mm256_fnmadd_pd(z0, r0, x);
    y = _mm_fnmadd_pd(_mm256_castpd256_pd128(z0), t0, y);
    x = _mm256_fnmadd_pd(z1, r1, x);
    y = _mm_fnmadd_pd(_mm256_castpd256_pd128(z1), t1, y);
    x = _mm256_fnmadd_pd(z2, r2, x);
    y = _mm_fnmadd_pd(_mm256_castpd256_pd128(z2), t2, y);
    _mm256_storeu_pd(row, x);
    _mm_storeu_pd(row + 4, y);
  }
}
#endif

void pair_update(int n1, int n2, int pn, const double *Lt, const double *Rt, double *out, i64 ld) {
#if defined(__AVX2__) && defined(__FMA__)
  if (pn == 3 && n1 == 6 && n2 == 6) return pair_update_663(Lt, Rt, out, ld);
#else
  if (pn == 3 && n1 == 6 && n2 == 6) return pair_update_t<6, 6, 3>(n1, n2, pn, Lt, Rt, out, ld);
#endif
  if (pn == 3) return pair_update_t<0, 0, 3>(n1, n2, pn, Lt, Rt, out, ld);
  pair_update_t<0, 0, 0>(n1, n2, pn, Lt, Rt, out, ld);
}

// pair_sweep for N1 x N2 blocks and points of 3, the block kept in a local array (registers):
// each entry's terms in pair_update_t's order.
template <int N1, int N2>
inline void pair_sweep_t(int n, const int *yc, const double *const *yp, const double *const *zp, double *out,
                         i64 ld) {
  double acc[N1 * N2];
  for (int a = 0; a < N1; ++a)
    for (int c = 0; c < N2; ++c) acc[a * N2 + c] = out[a * ld + c];
  for (int j = 0; j < n; ++j) {
    const double *L = zp[yc[j]];
    if (!L) continue;
    const double *R = yp[j];
    for (int a = 0; a < N1; ++a)
      for (int d = 0; d < 3; ++d) {
        const double z = L[d * N1 + a];
        for (int c = 0; c < N2; ++c) acc[a * N2 + c] -= z * R[d * N2 + c];
      }
  }
  for (int a = 0; a < N1; ++a)
    for (int c = 0; c < N2; ++c) out[a * ld + c] = acc[a * N2 + c];
}

// The sizes of the shared intrinsics' blocks beside the poses' 6 (a shared focal length, or
// one with a distortion parameter): n2 of them for n1 = N1, false for another n2.
template <int N1>
inline bool pair_sweep_n2(int n2, int n, const int *yc, const double *const *yp, const double *const *zp,
                          double *out, i64 ld) {
  switch (n2) {
    case 1: return pair_sweep_t<N1, 1>(n, yc, yp, zp, out, ld), true;
    case 2: return pair_sweep_t<N1, 2>(n, yc, yp, zp, out, ld), true;
    case 6: return pair_sweep_t<N1, 6>(n, yc, yp, zp, out, ld), true;
    default: return false;
  }
}

// How many points ahead pair_sweep asks for the couplings it reads.
constexpr int kAhead = 4;

// out less the terms of n points, in their order, each as pair_update gives it: point j's
// Y^T at yp[j] (n2 wide) and its Z^T at zp[yc[j]] (n1 wide; null: the point has no term).
// Not inlined: inside the tile loops the compiler runs out of vector registers and keeps an
// accumulator on the stack, which chains every term through memory.
__attribute__((noinline)) void pair_sweep(int n1, int n2, int pn, int n, const int *yc, const double *const *yp,
                                          const double *const *zp, double *out, i64 ld) {
#if defined(__AVX2__) && defined(__FMA__)
  if (pn == 3 && n1 == 6 && n2 == 6) {
    // The block in nine registers, named one by one (as an array the compiler keeps them on
    // the stack): x_a holds row a's first four entries, y_k the last two of rows 2k and 2k + 1.
    // Each point's three terms go in as pair_update_663 takes them: every entry's terms in the
    // same order, d ascending, each one fused multiply-subtract.
    __m256d x0 = _mm256_loadu_pd(out), x1 = _mm256_loadu_pd(out + ld), x2 = _mm256_loadu_pd(out + 2 * ld),
            x3 = _mm256_loadu_pd(out + 3 * ld), x4 = _mm256_loadu_pd(out + 4 * ld),
            x5 = _mm256_loadu_pd(out + 5 * ld);
    __m256d y0 = _mm256_loadu2_m128d(out + ld + 4, out + 4),
            y1 = _mm256_loadu2_m128d(out + 3 * ld + 4, out + 2 * ld + 4),
            y2 = _mm256_loadu2_m128d(out + 5 * ld + 4, out + 4 * ld + 4);
    for (int j = 0; j < n; ++j) {
      // The points' couplings lie apart in the chunk, where the hardware does not foresee the
      // next one: asked for a few points ahead, each 18 doubles of Z^T and of Y^T.
      if (j + kAhead < n) {
        const double *Rf = yp[j + kAhead], *Lf = zp[yc[j + kAhead]];
        for (int o = 0; o < 18; o += 8) {
          __builtin_prefetch(Rf + o);
          if (Lf) __builtin_prefetch(Lf + o);
        }
      }
      const double *L = zp[yc[j]];
      if (!L) continue;
      const double *R = yp[j];
      // Rolled: unrolled, the three terms' loads outnumber the registers left.
#pragma GCC unroll 1
      for (int d = 0; d < 3; ++d, L += 6, R += 6) {
        const __m256d r = _mm256_loadu_pd(R);
        const __m256d t = _mm256_broadcast_pd(reinterpret_cast<const __m128d *>(R + 4));  // t4 t5 t4 t5
        x0 = _mm256_fnmadd_pd(_mm256_broadcast_sd(L), r, x0);
        x1 = _mm256_fnmadd_pd(_mm256_broadcast_sd(L + 1), r, x1);
        x2 = _mm256_fnmadd_pd(_mm256_broadcast_sd(L + 2), r, x2);
        x3 = _mm256_fnmadd_pd(_mm256_broadcast_sd(L + 3), r, x3);
        x4 = _mm256_fnmadd_pd(_mm256_broadcast_sd(L + 4), r, x4);
        x5 = _mm256_fnmadd_pd(_mm256_broadcast_sd(L + 5), r, x5);
        // z_a z_a z_a+1 z_a+1 against t4 t5 t4 t5.
        y0 = _mm256_fnmadd_pd(_mm256_permute_pd(_mm256_broadcast_pd(reinterpret_cast<const __m128d *>(L)), 12), t, y0);
        y1 = _mm256_fnmadd_pd(_mm256_permute_pd(_mm256_broadcast_pd(reinterpret_cast<const __m128d *>(L + 2)), 12),
                              t, y1);
        y2 = _mm256_fnmadd_pd(_mm256_permute_pd(_mm256_broadcast_pd(reinterpret_cast<const __m128d *>(L + 4)), 12),
                              t, y2);
      }
    }
    _mm256_storeu_pd(out, x0);
    _mm256_storeu_pd(out + ld, x1);
    _mm256_storeu_pd(out + 2 * ld, x2);
    _mm256_storeu_pd(out + 3 * ld, x3);
    _mm256_storeu_pd(out + 4 * ld, x4);
    _mm256_storeu_pd(out + 5 * ld, x5);
    _mm256_storeu2_m128d(out + ld + 4, out + 4, y0);
    _mm256_storeu2_m128d(out + 3 * ld + 4, out + 2 * ld + 4, y1);
    _mm256_storeu2_m128d(out + 5 * ld + 4, out + 4 * ld + 4, y2);
    return;
  }
#endif
  if (pn == 3 && ((n1 == 1 && pair_sweep_n2<1>(n2, n, yc, yp, zp, out, ld)) ||
                  (n1 == 2 && pair_sweep_n2<2>(n2, n, yc, yp, zp, out, ld)) ||
                  (n1 == 6 && pair_sweep_n2<6>(n2, n, yc, yp, zp, out, ld))))
    return;
  for (int j = 0; j < n; ++j)
    if (const double *L = zp[yc[j]]) pair_update(n1, n2, pn, L, yp[j], out, ld);
}

// Position of block b in the ascending list [first, first + n), n if absent.
int find_block(const int *first, int n, int b) {
  return int(std::lower_bound(first, first + n, b) - first);
}

}  // namespace

void mapped_point_couplings(const MappedSchur &ms, const double *jac, int i, int upto, const i64 *zoff, double *Zt,
                            double *W) {
  const Layout &lay = ms.layout();
  const CameraMap &map = lay.cams;
  const int mnp = lay.mnp, cnp = lay.cnp, pnp = lay.pnp, jb = lay.jblk();
  const int *F = ms.point_blocks(i), nF = ms.point_nblocks(i);
  std::fill(Zt, Zt + zoff[upto], 0.0);
  for (int k = lay.rowptr[size_t(i)]; k < lay.rowptr[size_t(i) + 1]; ++k) {
    const int j = lay.colidx[size_t(k)];
    if (j < lay.mcon) continue;
    const double *A = jac + i64(k) * jb, *B = A + mnp * cnp;
    // W^T = B^T A (pnp x cnp), then its columns into the blocks of camera j.
    for (int d = 0; d < pnp; ++d) {
      double *w = W + d * cnp;
      for (int c = 0; c < cnp; ++c) w[c] = B[d] * A[c];
      for (int r = 1; r < mnp; ++r)
        for (int c = 0; c < cnp; ++c) w[c] += B[r * pnp + d] * A[r * cnp + c];
    }
    for (const int *q = map.cam_blocks_begin(j); q != map.cam_blocks_end(j); ++q) {
      const int b = *q;
      const int s = find_block(F, nF, b);
      if (s >= upto) continue;
      const int n = map.block_size(b);
      const int *cols = map.block_columns(b);
      double *z = Zt + zoff[s];
      for (int d = 0; d < pnp; ++d)
        for (int o = 0; o < n; ++o) z[d * n + o] += W[d * cnp + cols[o]];
    }
  }
}

namespace {

// Zeroes what the assembly of the block columns [B0, B1) adds to in a dense S: the columns
// down to their last row (the other kinds are zeroed by the caller).
void clear_columns(const CameraMap &map, int B0, int B1, const UnknownBlocks &S) {
  const i64 *start = map.block_starts();
  if (S.kind == UnknownBlocks::Kind::Dense)
    for (i64 r = 0; r < start[B1]; ++r) {
      double *row = S.base + r * S.ld;
      std::fill(row + start[B0], row + start[B1], 0.0);
    }
}

// U's blocks, the damping and e_a into block column B (rhs: its right-hand side, or null),
// camera by camera in ascending order.
void add_camera_terms(const Layout &lay, int B, const NormalEquations &ne, double mu, const UnknownBlocks &S,
                      double *rhs) {
  const CameraMap &map = lay.cams;
  const int cnp = lay.cnp;
  const int nB = map.block_size(B);
  const int *colsB = map.block_columns(B);
  if (rhs) std::fill(rhs, rhs + nB, 0.0);
  for (const int *q = map.block_cams_begin(B); q != map.block_cams_end(B); ++q) {
    const int j = *q;
    const double *Uj = ne.U + i64(j) * cnp * cnp, *eaj = ne.ea + i64(j) * cnp;
    if (rhs)
      for (int o = 0; o < nB; ++o) rhs[o] += eaj[colsB[o]];
    for (const int *qb = map.cam_blocks_begin(j); qb != map.cam_blocks_end(j); ++qb) {
      const int b = *qb;
      if (b > B) break;
      if (!S.holds(b, B)) continue;
      const int nb = map.block_size(b);
      const int *colsb = map.block_columns(b);
      const UnknownBlocks::Block blk = S.block(b, B);
      for (int o1 = 0; o1 < nb; ++o1)
        for (int o2 = 0; o2 < nB; ++o2) {
          const double u = Uj[colsb[o1] * cnp + colsB[o2]];
          if (blk.transposed)
            blk.p[o2 * blk.ld + o1] += u;
          else
            blk.p[o1 * blk.ld + o2] += u;
        }
    }
  }
  const UnknownBlocks::Block d = S.block(B, B);
  for (int o = 0; o < nB; ++o) d.p[o * d.ld + o] += mu;
}

// Point i's Z^T of its blocks up to hi and Y^T = V*^-1 Z^T of those in [lo, hi) (F: the
// blocks the point touches), block s's at Zt + zoff[s] and Yt + zoff[s], and its terms of the
// right-hand sides of the blocks in [lo, hi).
void point_terms(const MappedSchur &ms, int i, int lo, int hi, const NormalEquations &ne, const double *Vinv,
                 double *rhs, i64 *zoff, double *Zt, double *Yt, double *W) {
  const Layout &lay = ms.layout();
  const CameraMap &map = lay.cams;
  const int pnp = lay.pnp;
  const int *F = ms.point_blocks(i);
  zoff[0] = 0;
  for (int s = 0; s < hi; ++s) zoff[s + 1] = zoff[s] + i64(map.block_size(F[s])) * pnp;
  mapped_point_couplings(ms, ne.jac, i, hi, zoff, Zt, W);
  const double *Vi = Vinv + i64(i) * pnp * pnp, *ebi = ne.eb + i64(i) * pnp;
  for (int s = lo; s < hi; ++s) {
    const int B = F[s], nB = map.block_size(B);
    const double *z = Zt + zoff[s];
    double *y = Yt + zoff[s];
    for (int d = 0; d < pnp; ++d)
      for (int o = 0; o < nB; ++o) {
        double v = 0.0;
        for (int e = 0; e < pnp; ++e) v += Vi[d * pnp + e] * z[e * nB + o];
        y[d * nB + o] = v;
      }
    if (rhs) {
      double *rB = rhs + map.block_start(B);
      for (int d = 0; d < pnp; ++d)
        for (int o = 0; o < nB; ++o) rB[o] -= ebi[d] * y[d * nB + o];
    }
  }
}

// Point i's terms of the block columns F[lo, hi): its couplings, then the pairs they close.
void add_point_terms(const MappedSchur &ms, int i, int lo, int hi, const NormalEquations &ne, const double *Vinv,
                     const UnknownBlocks &S, double *rhs, MappedSchur::Scratch &sc) {
  const CameraMap &map = ms.layout().cams;
  const int pnp = ms.layout().pnp;
  const int *F = ms.point_blocks(i);
  i64 *zoff = sc.zoff.data();
  double *Zt = sc.Zt.data(), *Yt = sc.Yt.data();
  point_terms(ms, i, lo, hi, ne, Vinv, rhs, zoff, Zt, Yt, sc.W.data());
  for (int s = lo; s < hi; ++s) {
    const int B = F[s], nB = map.block_size(B);
    const double *y = Yt + zoff[s];
    for (int s1 = 0; s1 <= s; ++s1) {
      const int b = F[s1], nb = map.block_size(b);
      if (!S.holds(b, B)) continue;
      const UnknownBlocks::Block blk = S.block(b, B);
      if (blk.transposed)
        pair_update(nB, nb, pnp, y, Zt + zoff[s1], blk.p, blk.ld);
      else
        pair_update(nb, nB, pnp, Zt + zoff[s1], y, blk.p, blk.ld);
    }
  }
}

// The points' terms of a dense S when they touch much of it (MappedSchur::tiled): rather than
// point by point, each sweeping all of its pairs of S, a chunk of points' couplings is made
// first, and S is then updated a tile of blocks at a time with every point of the chunk, so
// that the tile stays in the cache while the points stream past, and a block at a time within
// the tile, so that the block is loaded and stored once for the whole chunk. Each entry of S
// still takes the points' terms in ascending order of the points, as add_point_terms gives
// them.
void add_points_tiled(const MappedSchur &ms, int B0, int B1, const NormalEquations &ne, const double *Vinv,
                      const UnknownBlocks &S, double *rhs, MappedSchur::Scratch &sc) {
  const Layout &lay = ms.layout();
  const CameraMap &map = lay.cams;
  const int pnp = lay.pnp;
  const i64 *start = map.block_starts();
  const int *group = ms.tile_groups(), ngroups = ms.tile_ngroups();
  MappedSchur::Chunk &ck = sc.chunk;
  int i = lay.ncon;
  while (i < lay.n) {
    // The chunk: the next points touching a block column of [B0, B1), as many as fit.
    int np = 0;
    i64 used = 0, zused = 0;
    for (; i < lay.n && np < int(ck.point.size()); ++i) {
      const int *F = ms.point_blocks(i), nF = ms.point_nblocks(i);
      const int lo = find_block(F, nF, B0);
      if (lo == nF || F[lo] >= B1) continue;
      const int hi = find_block(F, nF, B1);
      i64 need = 0;
      for (int s = 0; s < hi; ++s) need += i64(map.block_size(F[s])) * pnp;
      if (np > 0 && (used + 2 * need > ck.buf_size || zused + hi + 1 > i64(ck.zoff.size()))) break;
      i64 *zoff = ck.zoff.data() + zused;
      double *Zt = ck.buf.get() + used, *Yt = Zt + need;
      point_terms(ms, i, lo, hi, ne, Vinv, rhs, zoff, Zt, Yt, sc.W.data());
      ck.point[size_t(np)] = i;
      ck.lo[size_t(np)] = lo;
      ck.hi[size_t(np)] = hi;
      ck.base[size_t(np)] = used;
      ck.zbase[size_t(np)] = zused;
      used += 2 * need;
      zused += hi + 1;
      ++np;
    }
    if (np == 0) break;
    // Tiles of S: the column groups of [B0, B1) against the row groups up to them. Each block
    // of a tile takes the terms of every point of the chunk that touches both its blocks, in
    // ascending order of the points, while it stays in registers.
    for (int gc = 0; gc < ngroups; ++gc) {
      const int C0 = std::max(group[gc], B0), C1 = std::min(group[gc + 1], B1);
      if (C0 >= C1) continue;
      std::fill(ck.ycount.begin(), ck.ycount.begin() + (C1 - C0), 0);
      for (int c = 0; c < np; ++c) {
        const int *F = ms.point_blocks(ck.point[size_t(c)]);
        const int lo = ck.lo[size_t(c)], hi = ck.hi[size_t(c)];
        const i64 *zoff = ck.zoff.data() + ck.zbase[size_t(c)];
        const double *Yt = ck.buf.get() + ck.base[size_t(c)] + zoff[hi];
        const int sa = lo + find_block(F + lo, hi - lo, C0);
        // A point that touches no column of the tile leaves its rows alone: its cursor is at hi.
        ck.cur[size_t(c)] = sa < hi && F[sa] < C1 ? 0 : hi;
        for (int s = sa; s < hi && F[s] < C1; ++s) {
          const size_t k = size_t(F[s] - C0), at = k * size_t(np) + size_t(ck.ycount[k]++);
          ck.yc[at] = c;
          ck.yp[at] = Yt + zoff[s];
        }
      }
      for (int gr = 0; gr < ngroups && group[gr] < C1; ++gr) {
        const int R0 = group[gr], R1 = std::min(group[gr + 1], C1);
        std::fill(ck.zp.begin(), ck.zp.begin() + i64(R1 - R0) * np, nullptr);
        for (int c = 0; c < np; ++c) {
          const int *F = ms.point_blocks(ck.point[size_t(c)]);
          const int hi = ck.hi[size_t(c)];
          const i64 *zoff = ck.zoff.data() + ck.zbase[size_t(c)];
          const double *Zt = ck.buf.get() + ck.base[size_t(c)];
          int s1 = ck.cur[size_t(c)];
          for (; s1 < hi && F[s1] < R1; ++s1) ck.zp[size_t(F[s1] - R0) * size_t(np) + size_t(c)] = Zt + zoff[s1];
          ck.cur[size_t(c)] = s1;
        }
        for (int B = C0; B < C1; ++B) {
          const size_t k = size_t(B - C0);
          const int n = ck.ycount[k];
          if (n == 0) continue;
          for (int b = R0; b < std::min(R1, B + 1); ++b)
            pair_sweep(map.block_size(b), map.block_size(B), pnp, n, ck.yc.data() + k * size_t(np),
                       ck.yp.data() + k * size_t(np), ck.zp.data() + size_t(b - R0) * size_t(np),
                       S.base + start[b] * S.ld + start[B], S.ld);
        }
      }
    }
  }
}

}  // namespace

void mapped_assemble_columns(const MappedSchur &ms, int B0, int B1, const NormalEquations &ne, const double *Vinv,
                             double mu, const UnknownBlocks &S, double *rhs, MappedSchur::Scratch &sc) {
  if (B0 >= B1) return;
  const Layout &lay = ms.layout();
  clear_columns(lay.cams, B0, B1, S);
  for (int B = B0; B < B1; ++B)
    add_camera_terms(lay, B, ne, mu, S, rhs ? rhs + lay.cams.block_start(B) : nullptr);
  if (lay.pnp == 0) return;
  if (S.kind == UnknownBlocks::Kind::Dense && ms.tiled()) return add_points_tiled(ms, B0, B1, ne, Vinv, S, rhs, sc);
  // The points, in ascending order, that touch a block column of the range.
  for (int i = lay.ncon; i < lay.n; ++i) {
    const int *F = ms.point_blocks(i), nF = ms.point_nblocks(i);
    const int lo = find_block(F, nF, B0);
    if (lo == nF || F[lo] >= B1) continue;
    add_point_terms(ms, i, lo, find_block(F, nF, B1), ne, Vinv, S, rhs, sc);
  }
}

}  // namespace SBA_KERNELS_NS
}  // namespace sba
