// SPDX-License-Identifier: BSD-3-Clause
#include "camera_map.h"

#include <algorithm>
#include <numeric>
#include <unordered_map>

namespace sba {

CameraMap::CameraMap(int m, int mcon, int cnp) : m_(m), mcon_(std::min(mcon, m)), cnp_(cnp) {
  const int free = cnp > 0 ? m - mcon_ : 0;
  nunknowns_ = free * cnp;
  block_start_.resize(size_t(free) + 1);
  for (int b = 0; b <= free; ++b) block_start_[size_t(b)] = i64(b) * cnp;
  held_start_.assign(size_t(std::max(m, 0)) + 1, 0);
}

namespace {

// An unknown before the unknowns are ordered: its parameter and its cameras (ascending).
struct Provisional {
  int column;
  std::vector<int> cams;
};

// How many free cameras have each key. A key of one camera only is that camera's own
// parameter after all.
std::unordered_map<i64, int> key_counts(const std::vector<i64> &share, int m, int mcon, int cnp) {
  std::unordered_map<i64, int> count;
  for (int j = mcon; j < m; ++j)
    for (int c = 0; c < cnp; ++c) {
      const i64 k = share[size_t(j) * size_t(cnp) + size_t(c)];
      if (k >= 0) ++count[k];
    }
  return count;
}

}  // namespace

CameraMap::CameraMap(int m, int mcon, int cnp, const std::vector<char> &held, const std::vector<i64> &share)
    : CameraMap(m, mcon, cnp) {
  if (cnp == 0) return;
  const size_t all = size_t(m) * size_t(cnp);
  for (int j = mcon_; j < m && !held.empty(); ++j) {
    for (int c = 0; c < cnp; ++c)
      if (held[size_t(j) * cnp + c]) held_cols_.push_back(c);
    held_start_[size_t(j) + 1] = int(held_cols_.size());
  }
  any_held_ = !held_cols_.empty();
  bool any_shared = false;
  if (!share.empty())
    for (const auto &kc : key_counts(share, m, mcon_, cnp)) any_shared = any_shared || kc.second > 1;
  if (any_shared) {
    shape_ = Shape::Blocks;
    number_in_blocks(held, share);
    return;
  }
  if (!any_held_) return;
  // Held parameters without sharing: the others numbered in order; S keeps its blocks.
  unknown_.assign(all, -1);
  int u = 0;
  for (int j = mcon_; j < m; ++j)
    for (int c = 0; c < cnp; ++c)
      if (!held[size_t(j) * cnp + c]) unknown_[size_t(j) * cnp + c] = u++;
  nunknowns_ = u;
}

// The unknowns numbered in blocks, the unknowns of one set of cameras, ordered by their first
// camera, then by set, each block's unknowns by parameter; and the index both ways between
// the cameras and the blocks.
void CameraMap::number_in_blocks(const std::vector<char> &held, const std::vector<i64> &share) {
  const int m = m_, cnp = cnp_;
  const std::unordered_map<i64, int> count = key_counts(share, m, mcon_, cnp);
  // The unknowns in the order the cameras' parameters meet them, and per camera parameter its
  // provisional unknown (-1 for a held or fixed one).
  std::vector<Provisional> prov;
  std::unordered_map<i64, int> by_key;
  std::vector<int> prov_of(size_t(m) * size_t(cnp), -1);
  for (int j = mcon_; j < m; ++j)
    for (int c = 0; c < cnp; ++c) {
      const size_t q = size_t(j) * cnp + c;
      if (!held.empty() && held[q]) continue;
      const i64 k = share[q];
      int u;
      if (k >= 0 && count.at(k) > 1) {
        const auto f = by_key.emplace(k, int(prov.size()));
        if (f.second) prov.push_back({c, {}});
        u = f.first->second;
      } else {
        u = int(prov.size());
        prov.push_back({c, {}});
      }
      prov[size_t(u)].cams.push_back(j);
      prov_of[q] = u;
    }
  std::vector<int> order(prov.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    const Provisional &pa = prov[size_t(a)], &pb = prov[size_t(b)];
    if (pa.cams != pb.cams) return pa.cams < pb.cams;
    return pa.column < pb.column;
  });
  const int K = int(prov.size());
  std::vector<int> final_of(static_cast<size_t>(K));
  nunknowns_ = K;
  copies_.resize(size_t(K));
  column_.resize(size_t(K));
  block_start_.clear();
  std::vector<const std::vector<int> *> block_cams;
  for (int q = 0; q < K; ++q) {
    const Provisional &pu = prov[size_t(order[size_t(q)])];
    if (q == 0 || pu.cams != prov[size_t(order[size_t(q) - 1])].cams) {
      block_start_.push_back(q);
      block_cams.push_back(&pu.cams);
    }
    final_of[size_t(order[size_t(q)])] = q;
    copies_[size_t(q)] = int(pu.cams.size());
    column_[size_t(q)] = pu.column;
  }
  block_start_.push_back(K);
  unknown_.assign(prov_of.size(), -1);
  for (size_t q = 0; q < prov_of.size(); ++q)
    if (prov_of[q] >= 0) unknown_[q] = final_of[size_t(prov_of[q])];
  const int nb = nblocks();
  block_cam_start_.assign(size_t(nb) + 1, 0);
  std::vector<std::vector<int>> cam_blocks(static_cast<size_t>(m));
  for (int b = 0; b < nb; ++b) {
    block_cam_start_[size_t(b) + 1] = block_cam_start_[size_t(b)] + int(block_cams[size_t(b)]->size());
    for (int j : *block_cams[size_t(b)]) {
      block_cams_.push_back(j);
      cam_blocks[size_t(j)].push_back(b);  // b ascends: each camera's list is sorted
    }
  }
  cam_start_.assign(size_t(m) + 1, 0);
  for (int j = 0; j < m; ++j) {
    cam_start_[size_t(j) + 1] = cam_start_[size_t(j)] + int(cam_blocks[size_t(j)].size());
    cam_blocks_.insert(cam_blocks_.end(), cam_blocks[size_t(j)].begin(), cam_blocks[size_t(j)].end());
  }
}

void CameraMap::index_points(int n, int ncon, const int *rowptr, const int *colidx) {
  pstart_.clear();
  pblocks_.clear();
  if (per_camera()) return;
  pstart_.assign(size_t(n) + 1, 0);
  std::vector<int> list;
  for (int i = 0; i < n; ++i) {
    list.clear();
    if (i >= ncon)
      for (int k = rowptr[i]; k < rowptr[i + 1]; ++k) {
        const int j = colidx[k];
        if (j >= mcon_) list.insert(list.end(), cam_blocks_begin(j), cam_blocks_end(j));
      }
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
    pblocks_.insert(pblocks_.end(), list.begin(), list.end());
    pstart_[size_t(i) + 1] = int(pblocks_.size());
  }
}

void CameraMap::reduce(const double *x_cams, double *x_s) const {
  const double *free = x_cams + i64(mcon_) * cnp_;
  if (per_camera()) {
    // Held parameters keep their rows of S (pinned): every entry is the parameter's own.
    std::copy(free, free + order(), x_s);
    return;
  }
  // Each unknown's copies added in ascending camera order.
  std::fill(x_s, x_s + nunknowns_, 0.0);
  const i64 first = i64(mcon_) * cnp_, len = order_of_params();
  const int *unknown = unknown_.data() + first;
  for (i64 q = 0; q < len; ++q)
    if (unknown[q] >= 0) x_s[unknown[q]] += free[q];
}

void CameraMap::reduce_diagonal(const double *U, double *d_s) const {
  std::vector<double> diag(size_t(m_) * size_t(cnp_), 0.0);
  for (int j = mcon_; j < m_; ++j)
    for (int a = 0; a < cnp_; ++a) diag[size_t(j) * cnp_ + a] = U[i64(j) * cnp_ * cnp_ + a * (cnp_ + 1)];
  reduce(diag.data(), d_s);
}

void CameraMap::expand(const double *x_s, double held_value, double *x_cams) const {
  const i64 first = i64(mcon_) * cnp_, len = order_of_params();
  double *free = x_cams + first;
  if (unknown_.empty()) {
    std::copy(x_s, x_s + len, free);
    return;
  }
  const int *unknown = unknown_.data() + first;
  if (per_camera()) {
    for (i64 q = 0; q < len; ++q) free[q] = unknown[q] >= 0 ? x_s[q] : held_value;
    return;
  }
  for (i64 q = 0; q < len; ++q) free[q] = unknown[q] >= 0 ? x_s[unknown[q]] : held_value;
}

void CameraMap::pin_held(double *dp) const {
  if (!any_held_) return;
  const i64 first = i64(mcon_) * cnp_, len = order_of_params();
  for (i64 q = 0; q < len; ++q)
    if (unknown_[size_t(first + q)] < 0) dp[first + q] = -0.0;
}

std::vector<double> CameraMap::reduce_matrix(const std::vector<double> &A) const {
  const i64 nA = order_of_params(), nS = nunknowns_;
  std::vector<double> Z(size_t(nS) * size_t(nS), 0.0);
  for (i64 r = 0; r < nA; ++r) {
    const int ur = unknown(mcon_ + int(r / cnp_), int(r % cnp_));
    if (ur < 0) continue;
    double *row = Z.data() + size_t(ur) * size_t(nS);
    for (i64 c = 0; c < nA; ++c) {
      const int uc = unknown(mcon_ + int(c / cnp_), int(c % cnp_));
      if (uc >= 0) row[uc] += A[size_t(r * nA + c)];
    }
  }
  return Z;
}

std::vector<double> CameraMap::expand_matrix(const std::vector<double> &Z) const {
  const i64 nA = order_of_params(), nS = nunknowns_;
  std::vector<double> A(size_t(nA) * size_t(nA));
  for (i64 r = 0; r < nA; ++r) {
    const int ur = unknown(mcon_ + int(r / cnp_), int(r % cnp_));
    for (i64 c = 0; c < nA; ++c) {
      const int uc = unknown(mcon_ + int(c / cnp_), int(c % cnp_));
      A[size_t(r * nA + c)] = ur < 0 || uc < 0 ? 0.0 : Z[size_t(ur * nS + uc)];
    }
  }
  return A;
}

}  // namespace sba
