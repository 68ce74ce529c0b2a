// SPDX-License-Identifier: BSD-3-Clause
// The numbers of the text formats (lib/formats/text_tokens.h, lib/formats/colmap_text.cpp):
// a COLMAP text model with awkward values (denormals, the largest double, -0, values that need
// all 17 digits) is written as the exact text it has always been and reads back to the same
// bits; g17 is printf's %.17g and the token reader takes what strtod takes, to the same value.
#include <gtest/gtest.h>

#include <cfloat>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "formats/colmap_io.h"
#include "formats/text_tokens.h"

namespace colmap = sbaformats::colmap;

namespace {

colmap::Model awkward_model() {
  colmap::Model m;
  colmap::Camera c;
  c.id = 1;
  c.model = colmap::kOpenCV;
  c.width = 640;
  c.height = 480;
  c.params = {0.1, 1.0 / 3, 1e16, -0.0, 4.9406564584124654e-324, -1e-300, DBL_MAX, -2.5e-7};
  m.cameras.push_back(c);
  colmap::Image im;
  im.id = 1;
  im.q = {1, -0.0, 2.2250738585072009e-308, 1e-10};
  im.t = {1e308, 123456789012345678.0, 1.0000000000000002};
  im.camera_id = 1;
  im.name = "a b.png";
  im.points = {{0.5, 1e-5, 1}, {100, 9007199254740992.0, colmap::kNoPoint}};
  m.images.push_back(im);
  colmap::Point3D p;
  p.id = 1;
  p.xyz = {1e17, 1e21, 2.2250738585072014e-308};
  p.rgb = {0, 128, 255};
  p.error = -0.0;
  p.track = {{1, 0}};
  m.points.push_back(p);
  return m;
}

std::string printf_g17(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::uint64_t bits(double v) {
  std::uint64_t w;
  std::memcpy(&w, &v, sizeof w);
  return w;
}

}  // namespace

TEST(ColmapTextNumbers, AwkwardValuesWrittenAsEverAndReadBackBitForBit) {
  const colmap::Model m = awkward_model();
  std::string error;
  ASSERT_TRUE(colmap::check_model(m, "awkward", &error)) << error;
  const colmap::Files f = colmap::format_model(m, colmap::Encoding::Text);
  EXPECT_EQ(f.cameras,
            "# Camera list with one line of data per camera:\n"
            "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
            "# Number of cameras: 1\n"
            "1 OPENCV 640 480 0.10000000000000001 0.33333333333333331 10000000000000000 -0 "
            "4.9406564584124654e-324 -1e-300 1.7976931348623157e+308 -2.4999999999999999e-07\n");
  EXPECT_EQ(f.images,
            "# Image list with two lines of data per image:\n"
            "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
            "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
            "# Number of images: 1\n"
            "1 1 -0 2.2250738585072009e-308 1e-10 1e+308 1.2345678901234568e+17 1.0000000000000002 1 a b.png\n"
            "0.5 1.0000000000000001e-05 1 100 9007199254740992 -1\n");
  EXPECT_EQ(f.points,
            "# 3D point list with one line of data per point:\n"
            "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
            "# Number of points: 1\n"
            "1 1e+17 1e+21 2.2250738585072014e-308 0 128 255 -0 1 0\n");

  colmap::Model back;
  ASSERT_TRUE(colmap::parse_cameras_text(f.cameras, "cameras.txt", &back.cameras, &error)) << error;
  ASSERT_TRUE(colmap::parse_images_text(f.images, "images.txt", &back.images, &error)) << error;
  ASSERT_TRUE(colmap::parse_points_text(f.points, "points3D.txt", &back.points, &error)) << error;
  // The binary encoding holds each double's bits: equal files, equal values, -0 included.
  const colmap::Files want = colmap::format_model(m, colmap::Encoding::Binary);
  const colmap::Files got = colmap::format_model(back, colmap::Encoding::Binary);
  EXPECT_EQ(got.cameras, want.cameras);
  EXPECT_EQ(got.images, want.images);
  EXPECT_EQ(got.points, want.points);
  EXPECT_EQ(bits(back.points[0].error), bits(-0.0));
}

// g17 must write what printf's %.17g writes, so that files written before and after read the
// same; the values read back are the same bits.
TEST(ColmapTextNumbers, G17IsPrintfAndReadsBack) {
  std::vector<double> values = {0.0,     -0.0,     DBL_MIN, -DBL_MIN, DBL_MAX, -DBL_MAX, DBL_TRUE_MIN,
                                DBL_EPSILON, 1e-310, 0.1,   1.0 / 3, 1e15,     1e16,    1e17,
                                1e21,    1e22,     123456789012345678.0, 9007199254740993.0, 0.000123};
  std::mt19937_64 rng(7);
  for (int k = 0; k < 100000; ++k) {
    std::uint64_t w = rng();
    if (k % 2) w &= 0x800fffffffffffffull | (rng() % 2 ? 0 : 0x3ff0000000000000ull);  // denormals and near 1
    double v;
    std::memcpy(&v, &w, sizeof v);
    if (std::isfinite(v)) values.push_back(v);
  }
  for (double v : values) {
    const std::string s = sbaformats::g17(v);
    ASSERT_EQ(s, printf_g17(v)) << "bits " << bits(v);
    std::string appended = "x";
    sbaformats::append_g17(&appended, v);
    ASSERT_EQ(appended, "x" + s);
    double back = 0;
    ASSERT_TRUE(sbaformats::decimal_number(std::string_view(s), &back)) << s;
    ASSERT_EQ(bits(back), bits(v)) << s;
  }
}

// The reader of tokens inside a text takes and refuses what strtod's reader does, to the same
// value: a '+', an underflow to a denormal or zero and an overflow included.
TEST(ColmapTextNumbers, TokenReaderAgreesWithStrtod) {
  const char *const tokens[] = {"1",      "-1",       "+1",      "+-1",     "-+1",     "++1",   "1.5",  ".5",
                                "5.",     ".",        "-",       "+",       "1e",      "1e+",   "1e-5", "1E5",
                                "1e400",  "-1e400",   "1e-400",  "-1e-400", "4.9e-324", "2e-324", "0x10", "-0x1p3",
                                "0X1",    "nan",      "NaN",     "inf",     "-Infinity", "INF",  "1.5x", "x1.5",
                                "00012",  "-0",       "0.000",   "1,5",     "1_000",   "\v1",   "1\f",  "",
                                "179769313486231570000000000000000000000000000000000000000000000000000000000000000000"
                                "0000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
                                "0000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
                                "000000000000000000000000000000000000000000000000000000000000000000000000000"};
  for (const char *tok : tokens) {
    double a = 12345, b = 12345;
    const bool in_text = sbaformats::decimal_number(std::string_view(tok), &a);
    const bool alone = sbaformats::decimal_number(std::string(tok), &b);
    EXPECT_EQ(in_text, alone) << "'" << tok << "'";
    if (in_text && alone && !std::isnan(a)) EXPECT_EQ(bits(a), bits(b)) << "'" << tok << "'";
  }
  // A token is its characters only: what follows it in the text is not read.
  double v = 0;
  const std::string text = "2.5e3 7";
  EXPECT_TRUE(sbaformats::decimal_number(std::string_view(text).substr(0, 3), &v));
  EXPECT_EQ(v, 2.5);
  EXPECT_FALSE(sbaformats::decimal_number(std::string_view(text).substr(0, 4), &v));
}
