// SPDX-License-Identifier: BSD-3-Clause
// The block pattern of the reduced camera system (src/schur_pattern.h) of small problems
// written out by hand, per camera and over shared unknowns, the count that stops early, and
// the AMD ordering of the block graph.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <string>
#include <vector>

#include "camera_unknowns.h"
#include "layout.h"
#include "schur_pattern.h"
#include "suitesparse_status.h"

namespace {

using sba::i64;

// Four cameras of two parameters and four points: point 0 (fixed, ncon 1) seen by cameras 0
// and 2, point 1 by 0 and 1, point 2 by 1 and 2, point 3 by 3.
sba::Layout four_cameras() {
  const char vmask[16] = {1, 0, 1, 0,  //
                          1, 1, 0, 0,  //
                          0, 1, 1, 0,  //
                          0, 0, 0, 1};
  sba::Layout lay;
  std::string msg;
  EXPECT_TRUE(sba::build_layout(lay, sba::Mode::MotStr, 4, 4, 0, 1, 2, 3, 2, vmask, &msg)) << msg;
  return lay;
}

TEST(SchurPattern, PerCameraBlocksAreCoupledByFreePoints) {
  const sba::Layout lay = four_cameras();
  sba::SchurPattern pat;
  ASSERT_TRUE(sba::schur_pattern(lay, 100, &pat));
  // Column by column, the upper triangle: (0,0); (0,1) (1,1); (1,2) (2,2); (3,3). The fixed
  // point 0 couples nothing: no (0,2).
  EXPECT_EQ(pat.colstart, (std::vector<i64>{0, 1, 3, 5, 6}));
  EXPECT_EQ(pat.rows, (std::vector<int>{0, 0, 1, 1, 2, 3}));
  EXPECT_EQ(pat.nblocks(), 4);
  EXPECT_EQ(pat.nnz(), 6);
}

TEST(SchurPattern, CountingStopsPastTheLimit) {
  sba::SchurPattern pat;
  EXPECT_FALSE(sba::schur_pattern(four_cameras(), 3, &pat));
  EXPECT_TRUE(sba::schur_pattern(four_cameras(), 6, &pat));
}

TEST(SchurPattern, SharedBlocksAreCoupledByCommonCamerasToo) {
  sba::Layout lay = four_cameras();
  // Parameter 1 shared by cameras 2 and 3. Blocks by their cameras: 0 {0}: camera 0's two;
  // 1 {1}: camera 1's two; 2 {2}: camera 2's parameter 0; 3 {2, 3}: the shared one; 4 {3}:
  // camera 3's parameter 0.
  const int group[8] = {-1, -1, -1, -1, -1, 0, -1, 0};
  sba::CameraParamOptions o;
  o.param_group = group;
  lay.cams = sba::make_camera_map(o, lay);
  ASSERT_EQ(lay.cams.nblocks(), 5);
  sba::SchurPattern pat;
  ASSERT_TRUE(sba::schur_pattern(lay, 100, &pat));
  // Point 1 couples 0 and 1; point 2 blocks 1, 2 and 3; point 3 blocks 3 and 4; camera 2
  // blocks 2 and 3, camera 3 blocks 3 and 4.
  EXPECT_EQ(pat.colstart, (std::vector<i64>{0, 1, 3, 5, 8, 10}));
  EXPECT_EQ(pat.rows, (std::vector<int>{0, 0, 1, 1, 2, 1, 2, 3, 3, 4}));
}

// Three cameras of two parameters; point 0 seen by cameras 0 and 2, point 1 by all three,
// point 2 by 1 and 2: column 2 fills up at point 1, and point 2 has nothing to add to it.
sba::Layout full_three() {
  const char vmask[9] = {1, 0, 1,  //
                         1, 1, 1,  //
                         0, 1, 1};
  sba::Layout lay;
  std::string msg;
  EXPECT_TRUE(sba::build_layout(lay, sba::Mode::MotStr, 3, 3, 0, 0, 2, 3, 2, vmask, &msg)) << msg;
  return lay;
}

TEST(SchurPattern, ColumnsThatFillUpHoldEveryBlockOnce) {
  sba::SchurPattern pat;
  ASSERT_TRUE(sba::schur_pattern(full_three(), 100, &pat));
  EXPECT_EQ(pat.colstart, (std::vector<i64>{0, 1, 3, 6}));
  EXPECT_EQ(pat.rows, (std::vector<int>{0, 0, 1, 0, 1, 2}));
  // Parameter 1 shared by all three cameras: blocks 0, 1, 2 each camera's parameter 0 and
  // block 3 the shared one, which every camera and point couples to the others.
  sba::Layout lay = full_three();
  const int group[6] = {-1, 0, -1, 0, -1, 0};
  sba::CameraParamOptions o;
  o.param_group = group;
  lay.cams = sba::make_camera_map(o, lay);
  ASSERT_EQ(lay.cams.nblocks(), 4);
  ASSERT_TRUE(sba::schur_pattern(lay, 100, &pat));
  EXPECT_EQ(pat.colstart, (std::vector<i64>{0, 1, 3, 6, 10}));
  EXPECT_EQ(pat.rows, (std::vector<int>{0, 0, 1, 0, 1, 2, 0, 1, 2, 3}));
}

TEST(SchurPattern, AmdOrdersEveryBlockOnce) {
  sba::SchurPattern pat;
  ASSERT_TRUE(sba::schur_pattern(four_cameras(), 100, &pat));
  double info[AMD_INFO];
  std::vector<int> order = sba::amd_block_order(pat, info);
  // The block graph is a path 0-1-2 and 3 alone: no fill whatever the order.
  EXPECT_EQ(info[AMD_LNZ], 2.0);
  std::sort(order.begin(), order.end());
  std::vector<int> all(4);
  std::iota(all.begin(), all.end(), 0);
  EXPECT_EQ(order, all);
}

}  // namespace
