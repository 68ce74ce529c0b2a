/* SPDX-License-Identifier: BSD-3-Clause */
// How the camera parameters in p map to the unknowns of the reduced camera system: which are
// held, and which cameras share an unknown (sba_ext.h: cam_fixed, cam_param_group,
// cam_group/cam_shared). camera_unknowns.h builds it; every layer that sees the camera side
// of the normal equations reads it from the Layout.
//
// Without sharing, each free camera parameter is an unknown of its own, in order: camera j's
// parameter c is unknown (j - mcon) cnp + c, sba 1.6's layout, and the solvers work on the
// per-camera blocks they always did. A held parameter stays one of them, pinned: its Jacobian
// column is zeroed where the Jacobian is made and its step is -0.0, which leaves its bits as
// they are (-0.0 is the identity of addition).
//
// With sharing, the unknowns come in blocks, as the parameter blocks of a Ceres problem: the
// unknowns that the same set of cameras share form one block (a camera's own parameters, a
// lens shared by the images of one physical camera, a frame's pose shared by the images taken
// at one instant). Block b's unknowns are [block_start[b], block_start[b + 1]); unknown u is
// column column[u] of every camera of its block. A camera's parameters fall into the blocks it
// touches, each of its columns in exactly one. Cameras that share a block are coupled in the
// reduced camera system through its blocks, as cameras that see a common point are.
#ifndef SBA_SRC_CAMERA_MAP_H
#define SBA_SRC_CAMERA_MAP_H

#include <vector>

namespace sba {

struct CameraMap {
  // m * cnp flags, camera j's at j * cnp: the held parameters. Empty: none is held.
  std::vector<char> held;

  // The rest is empty unless some parameter is shared (shared()).
  int nunknowns = 0;
  std::vector<int> unknown;      // m * cnp: the unknown of camera j's parameter c; -1 below mcon
  std::vector<int> copies;       // per unknown: how many camera parameters it is
  std::vector<int> column;       // per unknown: the camera parameter it is in each of its cameras
  std::vector<int> block_start;  // nblocks + 1
  std::vector<int> cam_start, cam_blocks;    // camera j's blocks: [cam_start[j], cam_start[j + 1]), ascending
  std::vector<int> block_cam_start, block_cams;  // block b's cameras, ascending

  bool shared() const { return !block_start.empty(); }
  bool any_held() const { return !held.empty(); }
  int nblocks() const { return shared() ? int(block_start.size()) - 1 : 0; }
  int block_size(int b) const { return block_start[size_t(b) + 1] - block_start[size_t(b)]; }
  // The camera parameters of block b's unknowns, in unknown order.
  const int *block_columns(int b) const { return column.data() + block_start[size_t(b)]; }
};

}  // namespace sba

#endif
