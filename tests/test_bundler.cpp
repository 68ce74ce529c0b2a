// SPDX-License-Identifier: BSD-3-Clause
// Bundler's bundle files and image lists (lib/formats/bundler_io.h): the round trip, the
// reader on malformed input, and the rotations it converts. sbarefine on bundles:
// test_sbarefine.cpp.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "cameras/bal_camera.h"
#include "colmap_fixtures.h"
#include "formats/bundler_io.h"

namespace bundler = sbaformats::bundler;
namespace euclidean = sbacameras::euclidean;
namespace bal_camera = sbacameras::bal;

namespace {

using namespace refinetest;  // NOLINT: the helpers of the format tests

TEST(Bundler, RoundTripAndAnUnregisteredCamera) {
  const std::string dir = temp_dir("bundler_rt");
  const Scene s = make_scene(dir, euclidean::CameraKind::VaryingIntrinsics, 6, 50);
  bundler::Bundle b = make_bundle(s);
  b.cameras.push_back({});  // a camera Bundler could not place: all zeros
  const std::string text = bundler::format_bundle(b);
  EXPECT_EQ(text.rfind("# Bundle file v0.3\n7 50\n", 0), 0u);
  bundler::Bundle back;
  std::string error;
  ASSERT_TRUE(bundler::parse_bundle(text, "b.out", &back, &error)) << error;
  EXPECT_EQ(bundler::format_bundle(back), text);
  ASSERT_EQ(back.cameras.size(), 7u);
  EXPECT_EQ(back.cameras[3].R, b.cameras[3].R);
  EXPECT_EQ(back.points[7].views.size(), b.points[7].views.size());
  EXPECT_EQ(back.points[7].views[0].x, b.points[7].views[0].x);
  EXPECT_EQ(back.points[7].rgb, b.points[7].rgb);
  EXPECT_FALSE(back.cameras[6].registered());
}

TEST(Bundler, ReaderErrors) {
  const std::string cam = "1 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 -3\n";
  const Bad cases[] = {
      {"# Bundle v0.3\n", "b.out:1: expected the header '# Bundle file v0.3'"},
      {"# Bundle file v0.3\n1 1\n1 0 0\n1 0 0\n0 1 0\n0 0 2\n0 0 0\n0 0 0\n0 0 0\n0\n",
       "b.out:6: camera 0: R is not a rotation"},
      {"# Bundle file v0.3\n1 100000000\n1 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 -3\n0 0 0\n",
       "b.out: the counts (1 cameras, 100000000 points) need more numbers than the file holds"},
      {"# Bundle file v0.3\n1 1\n1 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 -3\n0 0 0\n1 2\n",
       "b.out:9: the file ends before point 0 blue"},
      {"# Bundle file v0.3\n1 -1\n", "b.out:2: the number of points is -1, expected 0..268435456"},
  };
  for (const Bad &b : cases) {
    bundler::Bundle out;
    std::string error;
    EXPECT_FALSE(bundler::parse_bundle(b.text, "b.out", &out, &error)) << b.text;
    EXPECT_EQ(error, b.message);
  }
  const std::string head = "# Bundle file v0.3\n2 1\n" + cam + "0 0 0\n0 0 0\n0 0 0\n0 0 0\n0 0 0\n";
  const Bad points[] = {
      {"0 0 0\n1 2 256\n0\n", "b.out:14: point 0 blue is 256, expected 0..255"},
      {"0 0 0\n1 2 3\n1 2 0 1 2\n", "b.out:15: point 0 camera index is 2, expected 0..1"},
      {"0 0 0\n1 2 3\n2 0 0 1 2 0 1 1 2\n", "b.out:15: point 0 is seen twice by camera 0"},
      {"0 0 0\n1 2 3\n1 1 0 1 2\n", "b.out:15: point 0 is seen by camera 1, which is not registered (f = 0)"},
      {"0 0 0\n1 2 3\n1 0 0 1 nan\n", "b.out:15: point 0 y must be a finite number, got 'nan'"},
      {"0 0 0\n1 2 3\n1 0 0 0x1 2\n", "b.out:15: point 0 x must be a finite number, got '0x1'"},
      {"0 0 0\n1 2 3\n1 0 0 1 2\n7\n", "b.out:16: data after the last point"},
  };
  for (const Bad &b : points) {
    bundler::Bundle out;
    std::string error;
    EXPECT_FALSE(bundler::parse_bundle(head + b.text, "b.out", &out, &error)) << b.text;
    EXPECT_EQ(error, b.message);
  }
  bundler::Bundle out;
  std::string error;
  EXPECT_TRUE(bundler::parse_bundle(head + "0 0 0\n1 2 3\n1 0 0 1 2\n", "b.out", &out, &error)) << error;
}

TEST(Bundler, ImageList) {
  const std::string text = "images/a.jpg\nimages/b.jpg 0 812.5\r\n  c.jpg\t0 1e3 \n";
  bundler::ImageList list;
  std::string error;
  ASSERT_TRUE(bundler::parse_list(text, "list.txt", &list, &error)) << error;
  EXPECT_EQ(list.names, (std::vector<std::string>{"images/a.jpg", "images/b.jpg", "c.jpg"}));
  EXPECT_EQ(list.text, text);
  ASSERT_TRUE(bundler::parse_list("a.jpg", "list.txt", &list, &error)) << error;
  EXPECT_EQ(list.names, std::vector<std::string>{"a.jpg"});
  const Bad cases[] = {
      {"a.jpg\n\nb.jpg\n", "list.txt:2: expected PATH or PATH 0 FOCAL, found 0 values"},
      {"a.jpg\nmy image.jpg\n", "list.txt:2: expected PATH or PATH 0 FOCAL, found 2 values"},
      {"a.jpg 1 500\n", "list.txt:1: expected 0 after the path, got '1'"},
      {"a.jpg 0 -500\n", "list.txt:1: the focal length must be a finite positive number, got '-500'"},
      {"a.jpg 0 nan\n", "list.txt:1: the focal length must be a finite positive number, got 'nan'"},
      {"a.jpg 0 500px\n", "list.txt:1: the focal length must be a finite positive number, got '500px'"},
      {"a.jpg 0 0x1p9\n", "list.txt:1: the focal length must be a finite positive number, got '0x1p9'"},
  };
  for (const Bad &b : cases) {
    EXPECT_FALSE(bundler::parse_list(b.text, "list.txt", &list, &error)) << b.text;
    EXPECT_EQ(error, b.message);
  }
}

TEST(Bundler, AngleAxisInvertsTheRotation) {
  const double ws[][3] = {{0, 0, 0}, {1e-9, -2e-9, 0}, {0.3, -0.2, 0.1}, {2, 1, -0.5},
                          {M_PI - 1e-9, 0, 0}, {0, 0, -M_PI}, {1.5, 1.5, 1.5}};
  for (const auto &w : ws) {
    std::array<double, 9> R;
    bal_camera::rotation_matrix(w, R.data());
    double v[3];
    bundler::angle_axis(R, v);
    std::array<double, 9> R2;
    bal_camera::rotation_matrix(v, R2.data());
    for (int k = 0; k < 9; ++k) EXPECT_NEAR(R2[k], R[k], 1e-12) << w[0] << " " << w[1] << " " << w[2];
  }
}

}  // namespace
