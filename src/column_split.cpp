// SPDX-License-Identifier: BSD-3-Clause
// The cost models behind split_schur_columns and the splits by projections (column_split.h).
#include "column_split.h"

#include <algorithm>
#include <cstddef>

namespace sba {
namespace {

// What assembling block columns [k0, k1) costs a thread, in multiply-adds: the block
// products of those columns, and the W and Y products of each track up to its last entry
// in the range, which the thread computes again where an earlier range has them too.
// Point i's part, with f its first free entry and [lo, hi) its entries in the range:
double track_cost(const Layout &lay, int f, int lo, int hi) {
  const double pair = double(lay.cnp) * lay.cnp * lay.pnp;
  const double prod = double(lay.mnp + lay.pnp) * lay.pnp * lay.cnp;
  const double a = lo - f + 1, b = hi - f;  // entry q2 takes q2 - f + 1 block products
  return prod * (hi - f) + pair * (a + b) * (b - a + 1) / 2;
}

// columns_cost(k0, b) for every b in [k0, nc] (into before[b]) and columns_cost(b, nc) for
// every b in [0, nc] (into after[b], when asked), in one pass over the index: as b moves,
// each track's part changes only where b passes one of its cameras.
void columns_costs(const Layout &lay, int k0, std::vector<double> &before,
                   std::vector<double> *after) {
  const int nc = lay.free_cams(), cn = lay.cnp, mcon = lay.mcon;
  std::vector<double> dbefore(size_t(nc) + 2, 0.0), dafter(size_t(nc) + 2, 0.0);
  for (int i = lay.ncon; i < lay.n && lay.pnp > 0; ++i) {
    const int r1 = lay.rowptr[i + 1];
    int f = lay.rowptr[i];
    while (f < r1 && lay.colidx[f] < mcon) ++f;
    // columns_cost(k0, b): hi grows past entry q when b passes its camera.
    int lo = f;
    while (lo < r1 && lay.colidx[lo] - mcon < k0) ++lo;
    double prev = 0.0;
    for (int q = lo; q < r1; ++q) {
      const double c = track_cost(lay, f, lo, q + 1);
      dbefore[size_t(lay.colidx[q] - mcon + 1)] += c - prev;
      prev = c;
    }
    // columns_cost(b, nc): lo is entry q for b in (camera of q - 1, camera of q].
    if (after)
      for (int q = f; q < r1; ++q) {
        const double c = track_cost(lay, f, q, r1);
        dafter[size_t(q > f ? lay.colidx[q - 1] - mcon + 1 : 0)] += c;
        dafter[size_t(lay.colidx[q] - mcon + 1)] -= c;
      }
  }
  before.assign(size_t(nc) + 1, 0.0);
  double run = 0.0;
  for (int b = 0; b <= nc; ++b) {
    run += dbefore[size_t(b)];
    if (b >= k0) before[size_t(b)] = double(b - k0) * cn * cn + run;
  }
  if (after) {
    after->assign(size_t(nc) + 1, 0.0);
    run = 0.0;
    for (int b = 0; b <= nc; ++b) {
      run += dafter[size_t(b)];
      (*after)[size_t(b)] = double(nc - b) * cn * cn + run;
    }
  }
}

// threads + 1 boundaries over the items [lo, hi), item i costing prefix[i + 1] - prefix[i].
std::vector<i64> balanced_split(const int *prefix, i64 lo, i64 hi, int threads) {
  std::vector<i64> b(size_t(threads) + 1, lo);
  b[size_t(threads)] = hi;
  const i64 total = i64(prefix[hi]) - prefix[lo];
  i64 i = lo;
  for (int t = 1; t < threads; ++t) {
    if (total <= 0) {
      b[size_t(t)] = lo + (hi - lo) * t / threads;
      continue;
    }
    const i64 want = prefix[lo] + total * t / threads;
    while (i < hi && prefix[i + 1] <= want) ++i;
    b[size_t(t)] = i;
  }
  return b;
}

}  // namespace

std::vector<i64> split_cameras_by_projections(const Layout &lay, int threads) {
  std::vector<int> before(size_t(lay.m) + 1, 0);  // projections of the cameras before each
  for (i64 k = 0; k < lay.nvis; ++k) ++before[size_t(lay.colidx[size_t(k)]) + 1];
  for (int j = 0; j < lay.m; ++j) before[size_t(j) + 1] += before[size_t(j)];
  return balanced_split(before.data(), lay.mcon, lay.m, threads);
}

std::vector<i64> split_points_by_projections(const Layout &lay, int first, int threads) {
  return balanced_split(lay.rowptr.data(), first, lay.n, threads);
}

// Block columns of S split over the threads so that their costs (columns_cost) match: each
// boundary in turn is the first column where the range before it outweighs the rest shared
// by the remaining threads. Each boundary walks the index once, so many threads on a large
// problem fall back to a split by block products alone.
std::vector<int> split_schur_columns(const Layout &lay, int threads) {
  const int nc = lay.free_cams();
  std::vector<int> split(size_t(threads) + 1, nc);
  split[0] = 0;
  if (threads == 1 || nc == 0) return split;
  if (double(threads) * double(lay.nvis) <= 1e8) {
    std::vector<double> before, after;
    for (int t = 0; t + 1 < threads; ++t) {
      const int k0 = split[size_t(t)];
      const double rest = threads - t - 1;
      columns_costs(lay, k0, before, t == 0 ? &after : nullptr);
      int k = std::min(k0 + 1, nc);  // k0 == nc: more threads than columns
      while (k < nc && before[size_t(k)] * rest < after[size_t(k)]) ++k;
      const auto load = [&](int c) { return std::max(before[size_t(c)], after[size_t(c)] / rest); };
      split[size_t(t) + 1] = k - 1 > k0 && load(k - 1) < load(k) ? k - 1 : k;
    }
    return split;
  }
  std::vector<double> work(size_t(nc), 1.0);
  for (int i = lay.ncon; i < lay.n && lay.pnp > 0; ++i) {
    int rank = 0;
    for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k)
      if (lay.colidx[k] >= lay.mcon) work[size_t(lay.colidx[k] - lay.mcon)] += ++rank;
  }
  double total = 0.0;
  for (double w : work) total += w;
  double acc = 0.0;
  int t = 1;
  for (int k = 0; k < nc && t < threads; ++k) {
    acc += work[size_t(k)];
    while (t < threads && acc >= total * t / threads) split[size_t(t++)] = k + 1;
  }
  return split;
}

}  // namespace sba
