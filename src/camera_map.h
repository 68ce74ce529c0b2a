/* SPDX-License-Identifier: BSD-3-Clause */
// How the camera parameters in p map to the unknowns of the camera side: which are held, and
// which cameras share an unknown (sba_ext.h: cam_fixed, cam_param_group, cam_group/cam_shared).
// The Layout carries one, built with it (the plain map) and refined once by the camera
// options (camera_unknowns.h); every layer that sees the camera side of the normal equations
// asks it, and none keeps a numbering of its own.
//
// The unknowns: a held parameter is none, a shared one is one for all of its copies, and
// every other free camera parameter is its own. Without sharing they are numbered in sba
// 1.6's order (camera j's parameter c before camera j's parameter c + 1, camera j's before
// camera j + 1's), so that without held parameters either, camera j's parameter c is unknown
// (j - mcon) cnp + c.
//
// The reduced camera system S comes in one of two shapes, which the map names (shape()):
//  - PerCamera, without sharing: S is over the free cameras' cnp x cnp blocks, sba 1.6's
//    layout, which the block kernels (kernels.h) assemble at their fixed sizes; that is what
//    keeps 1.6's bits and speed. A held parameter keeps its row of S, pinned: its Jacobian
//    column is zeroed where the Jacobian is made, so nothing of it reaches the normal
//    equations, and its step is -0.0 (pin_held), which leaves its bits as they are (-0.0 is
//    the identity of addition). S's order is then the free cameras' parameters, held ones
//    included, and row (j - mcon) cnp + c is camera j's parameter c.
//  - Blocks, with sharing: S is over the unknowns, in blocks as the parameter blocks of a
//    Ceres problem: the unknowns that the same set of cameras share form one block (a
//    camera's own parameters, a lens shared by the images of one physical camera, a frame's
//    pose shared by the images taken at one instant), assembled by mapped_schur.h. Block b's
//    unknowns are [block_start(b), block_start(b + 1)); unknown u is column column(u) of
//    every camera of its block. A camera's parameters fall into the blocks it touches, each
//    of its columns in exactly one. Cameras that share a block are coupled in S through its
//    blocks, as cameras that see a common point are.
// In both shapes S's blocks are numbered from 0 (nblocks, block_size, block_start), and the
// vectors of S's order are what reduce and expand map to and from the cameras' parameters.
#ifndef SBA_SRC_CAMERA_MAP_H
#define SBA_SRC_CAMERA_MAP_H

#include <cmath>
#include <cstddef>
#include <vector>

#include "types.h"

namespace sba {

class CameraMap {
 public:
  enum class Shape { PerCamera, Blocks };

  CameraMap() = default;
  // The plain map of m cameras of cnp parameters, the first mcon fixed: every free camera
  // parameter is its own unknown.
  CameraMap(int m, int mcon, int cnp);
  // The map with held and shared parameters. held: m * cnp flags, camera j's at j * cnp
  // (empty: none held). share: m * cnp keys (empty: none shared); the free cameras'
  // parameters whose keys are equal and not -1 are one unknown, and a key belongs to one
  // parameter c. A key that only one camera has makes that camera's parameter its own.
  // Cameras below mcon are fixed whatever their flags and keys say.
  CameraMap(int m, int mcon, int cnp, const std::vector<char> &held, const std::vector<i64> &share);
  // The point-to-block index of the Blocks shape (point_blocks): for n points, the first ncon
  // fixed, whose tracks are rowptr/colidx (the Layout's, cameras ascending). Nothing in the
  // PerCamera shape, whose point blocks are the free cameras of the point's track.
  void index_points(int n, int ncon, const int *rowptr, const int *colidx);

  Shape shape() const { return shape_; }
  bool per_camera() const { return shape_ == Shape::PerCamera; }
  int cameras() const { return m_; }
  int fixed_cameras() const { return mcon_; }
  int params() const { return cnp_; }

  // ---- the unknowns ----
  int unknowns() const { return nunknowns_; }
  // The unknown of camera j's parameter c; -1 for a camera below mcon or a held parameter.
  int unknown(int j, int c) const {
    if (j < mcon_) return -1;
    return unknown_.empty() ? (j - mcon_) * cnp_ + c : unknown_[std::size_t(j) * std::size_t(cnp_) + std::size_t(c)];
  }
  bool held(int j, int c) const { return any_held_ && j >= mcon_ && unknown(j, c) < 0; }
  bool any_held() const { return any_held_; }
  // Camera j's held parameters, ascending (none for a camera below mcon): the columns its
  // Jacobian blocks must have zero, listed once so that zeroing them costs no test per column.
  const int *held_begin(int j) const { return held_cols_.data() + held_start_[std::size_t(j)]; }
  const int *held_end(int j) const { return held_cols_.data() + held_start_[std::size_t(j) + 1]; }
  // Camera j's held columns zeroed in its Jacobian block A (rows x cnp, row-major). An entry
  // already +0.0 is not written, so that where a model zeroes them itself the Jacobian's
  // cache lines stay clean.
  void zero_held(int j, int rows, double *A) const {
    for (const int *c = held_begin(j); c != held_end(j); ++c)
      for (int r = 0; r < rows; ++r) {
        double &x = A[r * cnp_ + *c];
        if (x != 0.0 || std::signbit(x)) x = 0.0;
      }
  }
  // Whether the unknowns are the free cameras' parameters themselves, in order (none held,
  // none shared): every map to and from them is then the identity.
  bool plain() const { return unknown_.empty(); }
  // Whether some unknown is shared by several cameras (then the shape is Blocks).
  bool shared() const { return shape_ == Shape::Blocks; }
  // How many camera parameters unknown u is.
  int copies(int u) const { return copies_.empty() ? 1 : copies_[std::size_t(u)]; }

  // ---- S's order and blocks ----
  // Block b's rows are [block_start(b), block_start(b + 1)); order() = block_start(nblocks()).
  i64 order() const { return block_start_.back(); }
  int nblocks() const { return int(block_start_.size()) - 1; }
  int block_size(int b) const { return int(block_start_[std::size_t(b) + 1] - block_start_[std::size_t(b)]); }
  i64 block_start(int b) const { return block_start_[std::size_t(b)]; }
  const i64 *block_starts() const { return block_start_.data(); }
  // The row of S of camera j's parameter c (a free camera's): its unknown in the Blocks
  // shape, -1 if held; its place in its camera's block in the PerCamera shape.
  i64 row(int j, int c) const { return per_camera() ? i64(j - mcon_) * cnp_ + c : i64(unknown(j, c)); }

  // Blocks shape only: the camera parameters of block b's unknowns, in unknown order; block
  // b's cameras and camera j's blocks, each ascending; point i's blocks, ascending.
  const int *block_columns(int b) const { return column_.data() + block_start_[std::size_t(b)]; }
  const int *block_cams_begin(int b) const { return block_cams_.data() + block_cam_start_[std::size_t(b)]; }
  const int *block_cams_end(int b) const { return block_cams_.data() + block_cam_start_[std::size_t(b) + 1]; }
  int block_ncams(int b) const { return block_cam_start_[std::size_t(b) + 1] - block_cam_start_[std::size_t(b)]; }
  const int *cam_blocks_begin(int j) const { return cam_blocks_.data() + cam_start_[std::size_t(j)]; }
  const int *cam_blocks_end(int j) const { return cam_blocks_.data() + cam_start_[std::size_t(j) + 1]; }
  const int *point_blocks(int i) const { return pblocks_.data() + pstart_[std::size_t(i)]; }
  int point_nblocks(int i) const { return pstart_[std::size_t(i) + 1] - pstart_[std::size_t(i)]; }

  // ---- vectors over the cameras' parameters (m cnp entries, camera j's at j cnp) ----
  // x_cams reduced to S's order (P^T x): each row the sum of its copies, in ascending camera
  // order; the cameras below mcon left out.
  void reduce(const double *x_cams, double *x_s) const;
  // The diagonal of the cameras' blocks U (m cnp x cnp, row-major) reduced as reduce does.
  void reduce_diagonal(const double *U, double *d_s) const;
  // x_s expanded to the free cameras' parameters (P x): every copy gets its row's value, a
  // held parameter held_value; the cameras below mcon left alone.
  void expand(const double *x_s, double held_value, double *x_cams) const;
  // The held parameters' steps in dp (nvars, cameras first) set to -0.0.
  void pin_held(double *dp) const;

  // ---- matrices over the free cameras' parameters and over the unknowns ----
  // T^T A T, T the map from the unknowns to the free parameters ((j - mcon) cnp + c): A over
  // those parameters (row-major, square) to the unknowns, each unknown's row and column the
  // sums of its copies', held ones left out.
  std::vector<double> reduce_matrix(const std::vector<double> &A) const;
  // T Z T^T: Z over the unknowns back over the free parameters, zero for the held ones.
  std::vector<double> expand_matrix(const std::vector<double> &Z) const;

 private:
  // The free cameras' parameters, held ones included.
  i64 order_of_params() const { return i64(m_ - mcon_) * cnp_; }
  void number_in_blocks(const std::vector<char> &held, const std::vector<i64> &share);

  Shape shape_ = Shape::PerCamera;
  int m_ = 0, mcon_ = 0, cnp_ = 0;
  int nunknowns_ = 0;
  bool any_held_ = false;
  // held_begin/held_end's index: m + 1 starts into held_cols_ (all zero without held ones).
  std::vector<int> held_start_, held_cols_;
  // m * cnp: each camera parameter's unknown, -1 below mcon or held; empty for the plain map.
  std::vector<int> unknown_;
  // S's blocks' first rows, nblocks + 1 of them: the cameras' in the PerCamera shape.
  std::vector<i64> block_start_{0};
  // The Blocks shape's, empty in the PerCamera shape: per unknown its copies and its column;
  // the index both ways between the cameras and the blocks; each point's blocks.
  std::vector<int> copies_, column_;
  std::vector<int> cam_start_, cam_blocks_, block_cam_start_, block_cams_;
  std::vector<int> pstart_, pblocks_;
};

}  // namespace sba

#endif
