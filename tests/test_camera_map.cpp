// SPDX-License-Identifier: BSD-3-Clause
// The camera map (src/camera_map.h): the unknown of every camera parameter in its three
// regimes (plain, held, shared), S's blocks in either shape, the point-to-block index, and
// the maps of vectors, diagonals and matrices between the parameters and the unknowns.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "camera_map.h"

namespace {

using sba::CameraMap;
using sba::i64;

std::vector<int> unknowns_of(const CameraMap &map) {
  std::vector<int> u;
  for (int j = 0; j < map.cameras(); ++j)
    for (int c = 0; c < map.params(); ++c) u.push_back(map.unknown(j, c));
  return u;
}

TEST(CameraMap, PlainMapNumbersTheFreeParametersIn16Order) {
  const CameraMap map(4, 1, 3);
  EXPECT_EQ(map.shape(), CameraMap::Shape::PerCamera);
  EXPECT_TRUE(map.plain());
  EXPECT_FALSE(map.any_held());
  EXPECT_FALSE(map.shared());
  EXPECT_EQ(map.unknowns(), 9);
  EXPECT_EQ(map.order(), 9);
  EXPECT_EQ(unknowns_of(map), (std::vector<int>{-1, -1, -1, 0, 1, 2, 3, 4, 5, 6, 7, 8}));
  EXPECT_EQ(map.nblocks(), 3);
  EXPECT_EQ(map.block_size(2), 3);
  EXPECT_EQ(map.block_start(2), 6);
  EXPECT_EQ(map.row(2, 1), 4);
  EXPECT_EQ(map.copies(5), 1);
  // Vectors: the free cameras' part, as it is; expanded back, the fixed camera left alone.
  const std::vector<double> x{-1, -2, -3, 1, 2, 3, 4, 5, 6, 7, 8, 9};
  std::vector<double> r(9), back(12, 0.5);
  map.reduce(x.data(), r.data());
  EXPECT_EQ(r, std::vector<double>(x.begin() + 3, x.end()));
  map.expand(r.data(), 7.0, back.data());
  EXPECT_EQ(back, (std::vector<double>{0.5, 0.5, 0.5, 1, 2, 3, 4, 5, 6, 7, 8, 9}));
}

TEST(CameraMap, HeldParametersAreNoUnknownsButKeepTheirPinnedRowsOfS) {
  // Camera 1's parameter 0 and camera 2's parameter 1 held; camera 0 fixed (mcon 1), whose
  // flag is ignored.
  const std::vector<char> held{1, 0, 1, 0, 0, 1};
  const CameraMap map(3, 1, 2, held, {});
  EXPECT_EQ(map.shape(), CameraMap::Shape::PerCamera);
  EXPECT_FALSE(map.plain());
  EXPECT_TRUE(map.any_held());
  EXPECT_EQ(unknowns_of(map), (std::vector<int>{-1, -1, -1, 0, 1, -1}));
  EXPECT_EQ(map.unknowns(), 2);
  EXPECT_EQ(map.order(), 4);  // S keeps every free camera's block
  EXPECT_FALSE(map.held(0, 0));
  EXPECT_TRUE(map.held(1, 0));
  EXPECT_TRUE(map.held(2, 1));
  EXPECT_FALSE(map.held(2, 0));
  // Each camera's held columns, listed: none for the fixed camera.
  EXPECT_EQ(std::vector<int>(map.held_begin(0), map.held_end(0)), std::vector<int>{});
  EXPECT_EQ(std::vector<int>(map.held_begin(1), map.held_end(1)), std::vector<int>{0});
  EXPECT_EQ(std::vector<int>(map.held_begin(2), map.held_end(2)), std::vector<int>{1});
  const std::vector<double> x{9, 9, 1, 2, 3, 4};
  std::vector<double> r(4), back(6, 0.5);
  map.reduce(x.data(), r.data());
  EXPECT_EQ(r, (std::vector<double>{1, 2, 3, 4}));
  map.expand(r.data(), 7.0, back.data());
  EXPECT_EQ(back, (std::vector<double>{0.5, 0.5, 7, 2, 3, 7}));
  std::vector<double> dp{1, 1, 1, 1, 1, 1, 5};
  map.pin_held(dp.data());
  EXPECT_EQ(dp, (std::vector<double>{1, 1, 0, 1, 1, 0, 5}));
  EXPECT_TRUE(std::signbit(dp[2]));
  EXPECT_TRUE(std::signbit(dp[5]));
  EXPECT_FALSE(std::signbit(dp[0]));
}

// Three cameras of two parameters; parameter 1 shared by all three (one key), parameter 0
// each camera's own. Blocks by their sets of cameras, ascending: {0}, {0, 1, 2}, {1}, {2}.
CameraMap lens_map() {
  const std::vector<i64> share{-1, 5, -1, 5, -1, 5};
  return CameraMap(3, 0, 2, {}, share);
}

TEST(CameraMap, SharedParametersAreOneUnknownInBlocksOfTheirCameras) {
  const CameraMap map = lens_map();
  EXPECT_EQ(map.shape(), CameraMap::Shape::Blocks);
  EXPECT_TRUE(map.shared());
  EXPECT_EQ(map.unknowns(), 4);
  EXPECT_EQ(map.order(), 4);
  EXPECT_EQ(unknowns_of(map), (std::vector<int>{0, 1, 2, 1, 3, 1}));
  EXPECT_EQ(map.copies(1), 3);
  EXPECT_EQ(map.copies(2), 1);
  ASSERT_EQ(map.nblocks(), 4);
  for (int b = 0; b < 4; ++b) {
    EXPECT_EQ(map.block_size(b), 1);
    EXPECT_EQ(map.block_start(b), b);
  }
  EXPECT_EQ(map.block_columns(1)[0], 1);
  EXPECT_EQ(std::vector<int>(map.block_cams_begin(1), map.block_cams_end(1)), (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(std::vector<int>(map.cam_blocks_begin(1), map.cam_blocks_end(1)), (std::vector<int>{1, 2}));
  EXPECT_EQ(map.row(2, 1), 1);
}

TEST(CameraMap, ReduceSumsTheCopiesAndExpandSpreadsThem) {
  const CameraMap map = lens_map();
  const std::vector<double> x{1, 2, 3, 4, 5, 6};
  std::vector<double> r(4), back(6);
  map.reduce(x.data(), r.data());
  EXPECT_EQ(r, (std::vector<double>{1, 2 + 4 + 6, 3, 5}));
  map.expand(r.data(), 0.0, back.data());
  EXPECT_EQ(back, (std::vector<double>{1, 12, 3, 12, 5, 12}));
  // Round trip: P^T P multiplies each unknown by its copies.
  map.reduce(back.data(), r.data());
  EXPECT_EQ(r, (std::vector<double>{1, 36, 3, 5}));
  // The diagonal of each camera's block U_j (2 x 2), reduced as a vector.
  const std::vector<double> U{1, 9, 9, 2, 3, 9, 9, 4, 5, 9, 9, 6};
  map.reduce_diagonal(U.data(), r.data());
  EXPECT_EQ(r, (std::vector<double>{1, 2 + 4 + 6, 3, 5}));
}

TEST(CameraMap, AKeyOfOneCameraIsThatCamerasOwnParameter) {
  // Key 3 only on camera 1 (camera 0 is fixed): nothing is shared, the map is plain.
  const CameraMap map(2, 1, 2, {}, std::vector<i64>{3, -1, 3, -1});
  EXPECT_EQ(map.shape(), CameraMap::Shape::PerCamera);
  EXPECT_TRUE(map.plain());
  EXPECT_EQ(unknowns_of(map), (std::vector<int>{-1, -1, 0, 1}));
}

TEST(CameraMap, HeldAndSharedTogether) {
  // Parameter 0 shared by cameras 1 and 2 and held in both; parameter 1 shared by cameras 0
  // and 1; camera 2's parameter 1 its own.
  const std::vector<char> held{0, 0, 1, 0, 1, 0};
  const std::vector<i64> share{-1, 8, 4, 8, 4, -1};
  const CameraMap map(3, 0, 2, held, share);
  EXPECT_EQ(map.shape(), CameraMap::Shape::Blocks);
  EXPECT_TRUE(map.any_held());
  // Blocks: {0} camera 0's parameter 0; {0, 1} parameter 1; {2} camera 2's parameter 1.
  EXPECT_EQ(unknowns_of(map), (std::vector<int>{0, 1, -1, 1, -1, 2}));
  EXPECT_EQ(map.unknowns(), 3);
  EXPECT_TRUE(map.held(1, 0));
  EXPECT_FALSE(map.held(1, 1));
  std::vector<double> back(6, 0.5);
  const std::vector<double> u{1, 2, 3};
  map.expand(u.data(), -0.0, back.data());
  EXPECT_EQ(back, (std::vector<double>{1, 2, 0, 2, 0, 3}));
  EXPECT_TRUE(std::signbit(back[2]));
}

TEST(CameraMap, PointBlocksAreTheBlocksOfTheirFreeCameras) {
  CameraMap map = lens_map();
  // Point 0 seen by cameras 0 and 2, point 1 by camera 1, point 2 by camera 0.
  const int rowptr[] = {0, 2, 3, 4}, colidx[] = {0, 2, 1, 0};
  map.index_points(3, 0, rowptr, colidx);
  EXPECT_EQ(std::vector<int>(map.point_blocks(0), map.point_blocks(0) + map.point_nblocks(0)),
            (std::vector<int>{0, 1, 3}));
  EXPECT_EQ(std::vector<int>(map.point_blocks(1), map.point_blocks(1) + map.point_nblocks(1)),
            (std::vector<int>{1, 2}));
  // A fixed point (ncon 1) touches nothing.
  map.index_points(3, 1, rowptr, colidx);
  EXPECT_EQ(map.point_nblocks(0), 0);
  EXPECT_EQ(map.point_nblocks(2), 2);
}

TEST(CameraMap, MatricesReduceToTheUnknownsAndExpandBack) {
  const CameraMap map = lens_map();
  std::vector<double> A(36);
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) A[size_t(r * 6 + c)] = 10.0 * r + c;
  const std::vector<double> Z = map.reduce_matrix(A);
  ASSERT_EQ(Z.size(), 16u);
  // Unknown 1 is parameters 1, 3 and 5: its diagonal entry sums the 3 x 3 of them.
  EXPECT_EQ(Z[1 * 4 + 1], 11 + 13 + 15 + 31 + 33 + 35 + 51 + 53 + 55);
  EXPECT_EQ(Z[0 * 4 + 2], 2.0);
  EXPECT_EQ(Z[3 * 4 + 1], 41 + 43 + 45);
  const std::vector<double> B = map.expand_matrix(Z);
  EXPECT_EQ(B[3 * 6 + 5], Z[1 * 4 + 1]);
  EXPECT_EQ(B[4 * 6 + 0], Z[3 * 4 + 0]);
}

}  // namespace
