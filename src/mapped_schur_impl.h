/* SPDX-License-Identifier: BSD-3-Clause */
// The mapped assembly's hot loops (mapped_schur.h), compiled twice as the block kernels are
// (kernels_impl.h): by mapped_schur.cpp for any x86-64, and by mapped_schur_avx2.cpp with AVX2
// and FMA, each into its own namespace SBA_KERNELS_NS; MappedSchur picks the build the CPU
// runs.
#ifndef SBA_KERNELS_NS
#error "define SBA_KERNELS_NS before including mapped_schur_impl.h"
#endif

#include <algorithm>

#include "mapped_schur.h"

namespace sba {
namespace SBA_KERNELS_NS {
namespace {

// out[a][c] -= sum_d Lt[d][a] Rt[d][c] for a < n1, c < n2 (Lt pnp x n1, Rt pnp x n2): one
// point's term of a block of S, row by row along contiguous rows. N1, N2, P > 0 fix the sizes
// at compile time for the blocks that dominate (poses of 6 against poses of 6, points of 3),
// whose loops then unroll into registers.
template <int N1, int N2, int P>
inline void pair_update_t(int n1, int n2, int pn, const double *Lt, const double *Rt, double *out, i64 ld) {
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

void pair_update(int n1, int n2, int pn, const double *Lt, const double *Rt, double *out, i64 ld) {
  if (pn == 3 && n1 == 6 && n2 == 6) return pair_update_t<6, 6, 3>(n1, n2, pn, Lt, Rt, out, ld);
  if (pn == 3) return pair_update_t<0, 0, 3>(n1, n2, pn, Lt, Rt, out, ld);
  pair_update_t<0, 0, 0>(n1, n2, pn, Lt, Rt, out, ld);
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

// Point i's terms of the block columns F[lo, hi) (F: the blocks the point touches): Z^T of
// its blocks up to hi, then Y^T = V*^-1 Z^T of those in the range, the right-hand sides, and
// the pairs they close.
void add_point_terms(const MappedSchur &ms, int i, int lo, int hi, const NormalEquations &ne, const double *Vinv,
                     const UnknownBlocks &S, double *rhs, MappedSchur::Scratch &sc) {
  const Layout &lay = ms.layout();
  const CameraMap &map = lay.cams;
  const int pnp = lay.pnp;
  const int *F = ms.point_blocks(i);
  i64 *zoff = sc.zoff.data();
  double *Zt = sc.Zt.data(), *Yt = sc.Yt.data();
  zoff[0] = 0;
  for (int s = 0; s < hi; ++s) zoff[s + 1] = zoff[s] + i64(map.block_size(F[s])) * pnp;
  mapped_point_couplings(ms, ne.jac, i, hi, zoff, Zt, sc.W.data());
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

}  // namespace

void mapped_assemble_columns(const MappedSchur &ms, int B0, int B1, const NormalEquations &ne, const double *Vinv,
                             double mu, const UnknownBlocks &S, double *rhs, MappedSchur::Scratch &sc) {
  if (B0 >= B1) return;
  const Layout &lay = ms.layout();
  clear_columns(lay.cams, B0, B1, S);
  for (int B = B0; B < B1; ++B)
    add_camera_terms(lay, B, ne, mu, S, rhs ? rhs + lay.cams.block_start(B) : nullptr);
  if (lay.pnp == 0) return;
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
