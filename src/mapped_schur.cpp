// SPDX-License-Identifier: BSD-3-Clause
#include "mapped_schur.h"

#include <algorithm>

#include "isa.h"

#define SBA_KERNELS_NS portable
#include "mapped_schur_impl.h"

namespace sba {

UnknownBlocks::Block UnknownBlocks::block(int b, int B) const {
  switch (kind) {
    case Kind::Dense:
      return {base + i64(start[b]) * ld + start[B], ld, false};
    case Kind::Clusters:
      return {base + origin[b] + i64(pos[b]) * order[b] + pos[B], order[b], false};
    case Kind::Sparse:
      break;
  }
  const int pb = perm[b], pB = perm[B], c = std::min(pb, pB), r = std::max(pb, pB);
  const int *first = rows + colstart[c], *last = rows + colstart[c + 1];
  const i64 s = colstart[c] + (std::lower_bound(first, last, r) - first);
  return {base + colbase[c] + rowoff[s], height[c], pb > pB};
}

MappedSchur::MappedSchur(const Layout &lay, int threads, Assembly how, int tile, int chunk)
    : lay_(lay), avx2_(use_avx2_build()) {
  const CameraMap &map = lay.cams;
  const int nb = map.nblocks(), pnp = lay.pnp;
  // The work of each block column: the pairs it closes.
  std::vector<double> work(size_t(nb), 0.0);
  i64 ztotal = 0;  // every point's couplings
  for (int b = 0; b < nb; ++b) work[size_t(b)] = double(map.block_ncams(b)) * map.block_size(b);
  for (int i = 0; i < lay.n; ++i) {
    const int *list = point_blocks(i), nl = point_nblocks(i);
    i64 z = 0;
    double rows = 0.0;  // the unknowns of the point's blocks up to and including b
    for (int s = 0; s < nl; ++s) {
      const int b = list[s];
      z += i64(map.block_size(b)) * pnp;
      rows += map.block_size(b);
      work[size_t(b)] += rows * map.block_size(b) * pnp;
    }
    zmax_ = std::max(zmax_, z);
    ztotal += z;
  }
  // Contiguous ranges of block columns of about equal work, one per thread.
  const int T = std::max(threads, 1);
  double total = 0.0;
  for (double w : work) total += w;
  split_.assign(size_t(T) + 1, nb);
  split_[0] = 0;
  double acc = 0.0;
  int b = 0;
  for (int t = 1; t < T; ++t) {
    while (b < nb && acc + work[size_t(b)] / 2 < total * t / T) acc += work[size_t(b++)];
    split_[size_t(t)] = b;
  }
  scratch_.resize(size_t(T));
  int maxblocks = 0;
  double pairs = 0.0;
  for (int i = 0; i < lay.n; ++i) {
    maxblocks = std::max(maxblocks, point_nblocks(i));
    pairs += double(point_nblocks(i)) * point_nblocks(i);
  }
  // Tiles: runs of blocks up to `tile` unknowns wide, so that a tile of S stays in the
  // first-level cache while a chunk of points updates it.
  groups_.assign(1, 0);
  for (int g = 1; g < nb; ++g)
    if (map.block_start(g + 1) - map.block_start(groups_.back()) > tile) groups_.push_back(g);
  groups_.push_back(nb);
  for (size_t g = 0; g + 1 < groups_.size(); ++g) group_width_ = std::max(group_width_, groups_[g + 1] - groups_[g]);
  // Point by point, each point sweeps its pairs of S, the whole of S when it touches every
  // block; tile by tile, S is swept once a chunk. The tiles cost a look-up per point and tile,
  // which pays when the points touch, on average, a sixteenth of S's pairs or more (long
  // tracks, few cameras: a model that COLMAP's mapper is growing).
  tiled_ = how == Assembly::Tiled ||
           (how == Assembly::Auto && tile_ngroups() > 1 && pairs >= double(lay.n) * double(nb) * nb / 16.0);
  tiled_ = tiled_ && pnp > 0 && lay.n > lay.ncon;
  // A chunk holds at least one point of the longest couplings and up to about 2 MB of them,
  // but never more room than its points can use: a small problem, solved many times over (a
  // mapper's local adjustments), should not allocate 2 MB a thread each time.
  constexpr i64 kChunkDoubles = i64(1) << 18;
  const int chunk_points = std::max(std::min(chunk, lay.n - lay.ncon), 1);
  const i64 chunk_doubles =
      std::max(2 * zmax_, std::min({kChunkDoubles, 2 * ztotal, 2 * zmax_ * i64(chunk_points)}));
  for (Scratch &s : scratch_) {
    s.Zt.resize(size_t(zmax_) + 1);
    s.Yt.resize(size_t(zmax_) + 1);
    s.W.resize(size_t(pnp) * size_t(lay.cnp) + 1);
    s.zoff.resize(size_t(maxblocks) + 1);
    if (!tiled_) continue;
    Chunk &c = s.chunk;
    c.buf.reset(new double[size_t(chunk_doubles)]);
    c.buf_size = chunk_doubles;
    c.zoff.resize(size_t(std::max<i64>(maxblocks + 1, chunk_points * i64(maxblocks + 1) / 4)));
    for (std::vector<i64> *v : {&c.base, &c.zbase}) v->resize(chunk_points);
    for (std::vector<int> *v : {&c.point, &c.lo, &c.hi, &c.cur}) v->resize(chunk_points);
    c.ycount.resize(size_t(group_width_));
    const size_t table = size_t(group_width_) * size_t(chunk_points);
    c.yc.resize(table);
    c.yp.resize(table);
    c.zp.resize(table);
  }
}

void MappedSchur::point_couplings(const double *jac, int i, int upto, const i64 *zoff, double *Zt,
                                  double *W) const {
#if defined(SBA_HAVE_AVX2_BUILD)
  if (avx2_) return avx2::mapped_point_couplings(*this, jac, i, upto, zoff, Zt, W);
#endif
  portable::mapped_point_couplings(*this, jac, i, upto, zoff, Zt, W);
}

void MappedSchur::assemble(ThreadPool &pool, const NormalEquations &ne, const double *Vinv, double mu,
                           const UnknownBlocks &S, double *rhs) const {
  const int T = int(split_.size()) - 1;
  const auto part = [&](int t) {
    if (t >= T) return;
    const int B0 = split_[size_t(t)], B1 = split_[size_t(t) + 1];
    Scratch &sc = scratch_[size_t(t)];
#if defined(SBA_HAVE_AVX2_BUILD)
    if (avx2_) return avx2::mapped_assemble_columns(*this, B0, B1, ne, Vinv, mu, S, rhs, sc);
#endif
    portable::mapped_assemble_columns(*this, B0, B1, ne, Vinv, mu, S, rhs, sc);
  };
  if (T == 1 || pool.size() == 1) {
    for (int t = 0; t < T; ++t) part(t);
  } else {
    pool.run(part);
  }
}

}  // namespace sba
