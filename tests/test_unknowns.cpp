// SPDX-License-Identifier: BSD-3-Clause
// The unknowns of a solve on p itself (src/unknowns.h): how many there are with fixed, held
// and shared parameters, and the copies of a shared parameter tied to its first camera's
// value and given back bit for bit.
#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include "camera_unknowns.h"
#include "layout.h"
#include "unknowns.h"

namespace {

// Four cameras of three parameters, the first mcon fixed, and two points of three, the first
// ncon fixed, each seen by every camera.
sba::Layout four_cameras(int mcon, int ncon, const sba::CameraParamOptions &o) {
  sba::Layout lay;
  const std::vector<char> vmask(8, 1);
  std::string msg;
  EXPECT_TRUE(sba::build_layout(lay, sba::Mode::MotStr, 2, 4, mcon, ncon, 3, 3, 2, vmask.data(), &msg)) << msg;
  lay.cams = sba::make_camera_map(o, lay);
  return lay;
}

TEST(Unknowns, CountedWithFixedHeldAndSharedParameters) {
  EXPECT_EQ(sba::count_unknowns(four_cameras(0, 0, {})), 4 * 3 + 2 * 3);
  EXPECT_EQ(sba::count_unknowns(four_cameras(1, 1, {})), 3 * 3 + 3);
  const char held[3] = {0, 0, 1};
  sba::CameraParamOptions o;
  o.fixed = held;
  EXPECT_EQ(sba::count_unknowns(four_cameras(1, 0, o)), 3 * 2 + 6);
  const int group[4] = {-1, 0, 0, 0};
  const char shared[3] = {1, 0, 0};
  o.group = group;
  o.shared = shared;
  // Parameter 0 of cameras 1-3 is one unknown, parameter 2 held, parameter 1 each camera's.
  EXPECT_EQ(sba::count_unknowns(four_cameras(1, 0, o)), 1 + 3 + 6);
}

TEST(Unknowns, NoCopiesToTieWithoutSharing) {
  const sba::Layout lay = four_cameras(0, 0, {});
  std::vector<double> p(size_t(lay.nvars()), 1.5);
  EXPECT_TRUE(sba::tie_copies(lay, p.data()).empty());
  EXPECT_EQ(p, std::vector<double>(p.size(), 1.5));
}

TEST(Unknowns, CopiesTiedToTheirFirstCameraAndRestoredBitForBit) {
  // Parameter 1 shared by cameras 1, 2 and 3 (camera 0 fixed): tied to camera 1's value.
  const int group[12] = {-1, -1, -1, -1, 4, -1, -1, 4, -1, -1, 4, -1};
  sba::CameraParamOptions o;
  o.param_group = group;
  const sba::Layout lay = four_cameras(1, 0, o);
  std::vector<double> p(size_t(lay.nvars()));
  for (size_t q = 0; q < p.size(); ++q) p[q] = 0.25 * double(q);
  p[7] = -0.0;
  const std::vector<double> given = p;
  const std::vector<double> replaced = sba::tie_copies(lay, p.data());
  EXPECT_EQ(replaced, (std::vector<double>{-0.0, 2.5}));
  for (int j = 1; j < 4; ++j) EXPECT_EQ(p[size_t(3 * j + 1)], 1.0) << "camera " << j;
  std::vector<double> other = p;
  other[4] = other[7] = other[10] = 1.0;
  EXPECT_EQ(p, other);  // nothing else moved
  sba::restore_copies(lay, p.data(), replaced);
  EXPECT_EQ(std::memcmp(p.data(), given.data(), p.size() * sizeof(double)), 0);
}

}  // namespace
