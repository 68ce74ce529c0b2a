// SPDX-License-Identifier: BSD-3-Clause
#include "schur_pattern.h"

#include <algorithm>

#include "suitesparse_status.h"

namespace sba {

namespace {

// The Blocks shape (camera_map.h): blocks are coupled by a common point or a common camera.
bool mapped_pattern(const Layout &lay, i64 max_blocks, SchurPattern *pat) {
  std::vector<int> *rows = &pat->rows;
  const CameraMap &map = lay.cams;
  const int nb = map.nblocks();
  // Each block's free points.
  std::vector<i64> pstart(size_t(nb) + 1, 0);
  for (int i = lay.ncon; i < lay.n; ++i)
    for (int s = 0; s < map.point_nblocks(i); ++s) ++pstart[size_t(map.point_blocks(i)[s]) + 1];
  for (int b = 0; b < nb; ++b) pstart[size_t(b) + 1] += pstart[size_t(b)];
  std::vector<int> pts(static_cast<size_t>(pstart[size_t(nb)]));
  std::vector<i64> fill(pstart.begin(), pstart.end() - 1);
  for (int i = lay.ncon; i < lay.n; ++i)
    for (int s = 0; s < map.point_nblocks(i); ++s) pts[size_t(fill[size_t(map.point_blocks(i)[s])]++)] = i;
  std::vector<int> mark(size_t(nb), -1);
  pat->colstart.assign(size_t(nb) + 1, 0);
  const auto add = [&](int b, int B) {
    if (mark[size_t(b)] == B) return;
    mark[size_t(b)] = B;
    rows->push_back(b);
  };
  for (int B = 0; B < nb; ++B) {
    const size_t first = rows->size();
    // Once column B holds every block up to its own, nothing more can join it: with long
    // tracks, most columns are full after their first points.
    const auto full = [&] { return rows->size() - first == size_t(B) + 1; };
    add(B, B);
    for (i64 q = pstart[size_t(B)]; q < pstart[size_t(B) + 1] && !full(); ++q) {
      const int i = pts[size_t(q)];
      for (int s = 0; s < map.point_nblocks(i) && map.point_blocks(i)[s] < B; ++s) add(map.point_blocks(i)[s], B);
    }
    for (const int *j = map.block_cams_begin(B); j != map.block_cams_end(B) && !full(); ++j)
      for (const int *b = map.cam_blocks_begin(*j); b != map.cam_blocks_end(*j) && *b < B; ++b) add(*b, B);
    if (i64(rows->size()) > max_blocks) return false;
    std::sort(rows->begin() + long(first), rows->end());
    pat->colstart[size_t(B) + 1] = i64(rows->size());
  }
  return true;
}

}  // namespace

bool schur_pattern(const Layout &lay, i64 max_blocks, SchurPattern *pat) {
  std::vector<int> *rows = &pat->rows;
  std::vector<i64> *colstart = &pat->colstart;
  rows->clear();
  if (!lay.cams.per_camera()) return mapped_pattern(lay, max_blocks, pat);
  // The PerCamera shape: blocks are the free cameras, coupled by the points they see.
  const int nc = lay.free_cams();
  std::vector<int> colrow, mark(size_t(nc), -1);
  by_camera(lay, &colrow, nullptr);
  colstart->assign(size_t(nc) + 1, 0);
  for (int k = 0; k < nc; ++k) {
    const int cam = k + lay.mcon;
    const size_t first = rows->size();
    for (int s = lay.colptr[cam]; s < lay.colptr[cam + 1] && rows->size() - first < size_t(k) + 1; ++s) {
      const int i = colrow[size_t(s)];
      if (i < lay.ncon) continue;
      for (int q = lay.rowptr[i]; q < lay.rowptr[i + 1]; ++q) {
        const int j = lay.colidx[q] - lay.mcon;
        if (j < 0) continue;
        if (j > k) break;  // cameras ascend along a track
        if (mark[size_t(j)] != k) {
          mark[size_t(j)] = k;
          rows->push_back(j);
        }
      }
    }
    if (mark[size_t(k)] != k) rows->push_back(k);  // a camera without free points
    if (i64(rows->size()) > max_blocks) return false;
    std::sort(rows->begin() + long(first), rows->end());
    (*colstart)[size_t(k) + 1] = i64(rows->size());
  }
  return true;
}

std::vector<int> amd_block_order(const SchurPattern &pat, double *info) {
  const int nb = pat.nblocks();
  const std::vector<SuiteSparse_long> Ap(pat.colstart.begin(), pat.colstart.end()),
      Ai(pat.rows.begin(), pat.rows.end());
  std::vector<SuiteSparse_long> order(static_cast<size_t>(nb));
  // AMD orders the pattern of A + A^T, so the upper triangle is enough.
  const int status = amd_l_order(nb, Ap.data(), Ai.data(), order.data(), nullptr, info);
  if (status != AMD_OK && status != AMD_OK_BUT_JUMBLED) throw_amd_failure("amd_l_order", status);
  return std::vector<int>(order.begin(), order.end());
}

}  // namespace sba
