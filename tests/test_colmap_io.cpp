// SPDX-License-Identifier: BSD-3-Clause
// COLMAP sparse models (lib/formats/colmap_io.h, lib/formats/colmap_sba.h): the readers on
// malformed input, the text and binary round trips, the writer's replacement of a model, rigs and
// frames (COLMAP 4), and the image lists of --hold-poses. sbarefine on these models:
// test_sbarefine.cpp.
#include <gtest/gtest.h>

#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "colmap_fixtures.h"
#include "formats/colmap_check.h"
#include "formats/colmap_io.h"
#include "formats/text_tokens.h"

namespace colmap = sbaformats::colmap;
namespace euclidean = sbacameras::euclidean;

namespace {

using namespace refinetest;  // NOLINT: the helpers of the format tests

// ---- round trips ----

TEST(ColmapRoundTrip, TextAndBinary) {
  const std::string dir = temp_dir("roundtrip");
  const Scene s = make_scene(dir, euclidean::CameraKind::VaryingIntrinsicsDistortion);
  std::string error;
  ASSERT_TRUE(colmap::check_model(s.model, "generated", &error)) << error;
  for (colmap::Encoding e : {colmap::Encoding::Text, colmap::Encoding::Binary}) {
    const std::string out = dir + (e == colmap::Encoding::Text ? "/text" : "/binary");
    ASSERT_TRUE(colmap::write_model(out, s.model, e, &error)) << error;
    colmap::Model back;
    colmap::Encoding found;
    ASSERT_TRUE(colmap::read_model(out, &back, &found, &error)) << error;
    EXPECT_EQ(found, e);
    expect_same(s.model, back);
    // Written again, the files are the same bytes.
    const colmap::Files first = colmap::format_model(s.model, e), second = colmap::format_model(back, e);
    EXPECT_EQ(first.cameras, second.cameras);
    EXPECT_EQ(first.images, second.images);
    EXPECT_EQ(first.points, second.points);
    EXPECT_EQ(read_file(out + (e == colmap::Encoding::Text ? "/images.txt" : "/images.bin")), first.images);
  }
  // The binary sizes as COLMAP lays the records out: 8 + per camera 24 + 8 * 8 (OPENCV).
  EXPECT_EQ(colmap::format_model(s.model, colmap::Encoding::Binary).cameras.size(), 8u + 10u * (24u + 64u));
}

TEST(ColmapRoundTrip, EveryAcceptedCameraModelAndNamesWithBlanks) {
  const std::string text =
      "# comment\n"
      "1 SIMPLE_PINHOLE 640 480 500 320 240\n"
      "2 PINHOLE 640 480 500 510 320 240\n"
      "\n"
      "3 SIMPLE_RADIAL 640 480 500 320 240 0.125\n"
      "4 RADIAL 640 480 500 320 240 0.125 -0.5\n"
      "5 OPENCV 640 480 500 510 320 240 0.125 -0.5 1e-3 -2e-3\n";
  std::vector<colmap::Camera> cams;
  std::string error;
  ASSERT_TRUE(colmap::parse_cameras_text(text, "cameras.txt", &cams, &error)) << error;
  ASSERT_EQ(cams.size(), 5u);
  EXPECT_EQ(cams[4].params, (std::vector<double>{500, 510, 320, 240, 0.125, -0.5, 1e-3, -2e-3}));
  const std::string images = "7 1 0 0 0 0.5 0 2 3 my image.png\n100 200 -1\n9 0 1 0 0 0 0 1 3 b.png\n\n";
  std::vector<colmap::Image> ims;
  ASSERT_TRUE(colmap::parse_images_text(images, "images.txt", &ims, &error)) << error;
  ASSERT_EQ(ims.size(), 2u);
  EXPECT_EQ(ims[0].name, "my image.png");
  EXPECT_EQ(ims[0].points.size(), 1u);
  EXPECT_EQ(ims[0].points[0].point3d_id, colmap::kNoPoint);
  EXPECT_TRUE(ims[1].points.empty());
  colmap::Model m;
  m.cameras = cams;
  m.images = ims;
  const colmap::Files f = colmap::format_model(m, colmap::Encoding::Text);
  std::vector<colmap::Camera> cams2;
  std::vector<colmap::Image> ims2;
  ASSERT_TRUE(colmap::parse_cameras_text(f.cameras, "c", &cams2, &error)) << error;
  ASSERT_TRUE(colmap::parse_images_text(f.images, "i", &ims2, &error)) << error;
  EXPECT_EQ(colmap::format_model({cams2, ims2, {}}, colmap::Encoding::Binary).images,
            colmap::format_model(m, colmap::Encoding::Binary).images);
}

// COLMAP 4's eighteen camera models (names, ids and parameter counts as pycolmap's
// CameraModelId and Camera.params_info give them), read from text and written as binary with
// COLMAP's layout (24 bytes, then a double per parameter), read back the same.
TEST(ColmapRoundTrip, EighteenCameraModels) {
  const struct {
    const char *name;
    int params;
  } models[] = {{"SIMPLE_PINHOLE", 3},
                {"PINHOLE", 4},
                {"SIMPLE_RADIAL", 4},
                {"RADIAL", 5},
                {"OPENCV", 8},
                {"OPENCV_FISHEYE", 8},
                {"FULL_OPENCV", 12},
                {"FOV", 5},
                {"SIMPLE_RADIAL_FISHEYE", 4},
                {"RADIAL_FISHEYE", 5},
                {"THIN_PRISM_FISHEYE", 12},
                {"RAD_TAN_THIN_PRISM_FISHEYE", 16},
                {"SIMPLE_DIVISION", 4},
                {"DIVISION", 5},
                {"SIMPLE_FISHEYE", 3},
                {"FISHEYE", 4},
                {"EUCM", 6},
                {"EQUIRECTANGULAR", 2}};
  std::string text;
  std::size_t bytes = 8;
  for (int m = 0; m < 18; ++m) {
    text += std::to_string(m + 1) + " " + models[m].name + " 640 480";
    for (int k = 0; k < models[m].params; ++k) text += " " + std::to_string(500 - 3 * k) + ".25";
    text += "\n";
    bytes += 24 + 8 * static_cast<std::size_t>(models[m].params);
  }
  std::vector<colmap::Camera> cams, back;
  std::string error;
  ASSERT_TRUE(colmap::parse_cameras_text(text, "cameras.txt", &cams, &error)) << error;
  ASSERT_EQ(cams.size(), 18u);
  for (int m = 0; m < 18; ++m) {
    const colmap::Camera &c = cams[static_cast<std::size_t>(m)];
    EXPECT_EQ(c.model, m) << models[m].name;
    EXPECT_STREQ(colmap::camera_model_name(m), models[m].name);
    EXPECT_EQ(colmap::camera_model_params(m), models[m].params);
    ASSERT_EQ(c.params.size(), static_cast<std::size_t>(models[m].params)) << models[m].name;
    for (int k = 0; k < models[m].params; ++k)
      EXPECT_EQ(c.params[static_cast<std::size_t>(k)], 500 - 3 * k + 0.25) << models[m].name;
  }
  const std::string binary = colmap::format_model({cams, {}, {}}, colmap::Encoding::Binary).cameras;
  EXPECT_EQ(binary.size(), bytes);
  ASSERT_TRUE(colmap::parse_cameras_binary(binary, "cameras.bin", &back, &error)) << error;
  EXPECT_EQ(colmap::format_model({back, {}, {}}, colmap::Encoding::Text).cameras,
            colmap::format_model({cams, {}, {}}, colmap::Encoding::Text).cameras);
  EXPECT_EQ(colmap::camera_model_name(18), nullptr);
}

// ---- strictness ----

TEST(ColmapReader, CameraTextErrors) {
  const Bad cases[] = {
      {"1 RAD_TAN_THIN_PRISM_FISHEYE 640 480 1 2 3 4 5 6 7 8 9 10 11 12\n",
       "c.txt:1: camera 1: RAD_TAN_THIN_PRISM_FISHEYE has 16 parameters, found 12"},
      {"1 EQUIRECTANGULAR 640 480 640 480 1\n", "c.txt:1: camera 1: EQUIRECTANGULAR has 2 parameters, found 3"},
      {"4 EQUIRECTANGULAR 640 480 0 480\n", "c.txt:1: camera 4: EQUIRECTANGULAR's w must be positive, got 0"},
      {"4 EQUIRECTANGULAR 640 480 -640 480\n",
       "c.txt:1: camera 4: EQUIRECTANGULAR's w must be positive, got -640"},
      {"4 EQUIRECTANGULAR 640 480 640 -0\n", "c.txt:1: camera 4: EQUIRECTANGULAR's h must be positive, got -0"},
      {"1 SIMPLE_DIVISION 640 480 -500 320 240 0.1\n",
       "c.txt:1: camera 1: SIMPLE_DIVISION's f must be positive, got -500"},
      {"1 EUCM 640 480 500 0 320 240 0.5 1\n", "c.txt:1: camera 1: EUCM's fy must be positive, got 0"},
      {"1 FULL_OPENCV 640 480 1 2 3 4 5 6 7 8 9 10 11\n", "c.txt:1: camera 1: FULL_OPENCV has 12 parameters, found 11"},
      {"1 FISHY 640 480 1 2 3\n", "c.txt:1: unknown camera model 'FISHY'"},
      {"#\n1 PINHOLE 640 480 1 2 3\n", "c.txt:2: camera 1: PINHOLE has 4 parameters, found 3"},
      {"1 PINHOLE 640 480 1 2 3 nan\n", "c.txt:1: a camera parameter must be a finite number, got 'nan'"},
      {"-1 PINHOLE 640 480 1 2 3 4\n", "c.txt:1: CAMERA_ID must be an integer from 0 to 4294967295, got '-1'"},
      {"1 PINHOLE 640 480 1 2 3 4\n1 PINHOLE 640 480 1 2 3 4\n", "c.txt:2: camera 1 appears twice"},
      {"1 PINHOLE 640\n", "c.txt:1: expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[], found 3 values"},
      {"1 PINHOLE 640 480 0x1p9 500 320 240\n", "c.txt:1: a camera parameter must be a finite number, got '0x1p9'"},
      {"1 PINHOLE 640 480 0 500 320 240\n", "c.txt:1: camera 1: PINHOLE's fx must be positive, got 0"},
      {"1 PINHOLE 640 480 500 -500 320 240\n", "c.txt:1: camera 1: PINHOLE's fy must be positive, got -500"},
      {"3 SIMPLE_RADIAL 640 480 -1e-300 320 240 0\n",
       "c.txt:1: camera 3: SIMPLE_RADIAL's f must be positive, got -1e-300"},
      {"2 OPENCV 640 480 1e-300 1e300 320 240 0 0 0 0\n",
       "c.txt:1: camera 2: OPENCV's aspect ratio fy / fx overflows or underflows"},
  };
  for (const Bad &b : cases) {
    std::vector<colmap::Camera> cams;
    std::string error;
    EXPECT_FALSE(colmap::parse_cameras_text(b.text, "c.txt", &cams, &error)) << b.text;
    EXPECT_EQ(error, b.message);
  }
}

TEST(ColmapReader, ImageAndPointTextErrors) {
  const Bad images[] = {
      {"1 0 0 0 0 0 0 0 1 a.png\n\n", "i.txt:1: image 1: the quaternion is zero"},
      {"1 1 0 0 0 0 0 0 1 a.png\n", "i.txt:1: the image's line of POINTS2D (X Y POINT3D_ID ...) is missing"},
      {"1 1 0 0 0 0 0 0 1 a.png\n1 2\n", "i.txt:2: POINTS2D come in triples X Y POINT3D_ID, found 2 values"},
      {"1 1 0 0 0 0 0 0 1 a.png\n1 2 -2\n",
       "i.txt:2: POINT3D_ID must be -1 or an integer from 0 to 18446744073709551614, got '-2'"},
      {"1 1 0 0 0 0 inf 0 1 a.png\n\n", "i.txt:1: TY must be a finite number, got 'inf'"},
      {"1 1 0 0 0 0x1 0 0 1 a.png\n\n", "i.txt:1: TX must be a finite number, got '0x1'"},
  };
  for (const Bad &b : images) {
    std::vector<colmap::Image> ims;
    std::string error;
    EXPECT_FALSE(colmap::parse_images_text(b.text, "i.txt", &ims, &error)) << b.text;
    EXPECT_EQ(error, b.message);
  }
  const Bad points[] = {
      {"1 0 0 0 255 0 256 0.5 1 0\n", "p.txt:1: B must be an integer from 0 to 255, got '256'"},
      {"1 0 0 0 255 0 0 0.5 1\n",
       "p.txt:1: expected POINT3D_ID X Y Z R G B ERROR and pairs IMAGE_ID POINT2D_IDX, found 9 values"},
  };
  for (const Bad &b : points) {
    std::vector<colmap::Point3D> pts;
    std::string error;
    EXPECT_FALSE(colmap::parse_points_text(b.text, "p.txt", &pts, &error)) << b.text;
    EXPECT_EQ(error, b.message);
  }
}

TEST(ColmapReader, BinaryErrors) {
  const std::string dir = temp_dir("binerr");
  const Scene s = make_scene(dir, euclidean::CameraKind::VaryingIntrinsicsDistortion, 4, 30);
  colmap::Files f = colmap::format_model(s.model, colmap::Encoding::Binary);
  std::string error;
  std::vector<colmap::Camera> cams;
  std::vector<colmap::Image> ims;
  std::vector<colmap::Point3D> pts;
  // A model id beyond COLMAP's, and one that is negative as COLMAP's int32 reads it.
  std::string bad = f.cameras;
  bad[12] = 18;
  EXPECT_FALSE(colmap::parse_cameras_binary(bad, "c.bin", &cams, &error));
  EXPECT_EQ(error, "c.bin: byte 8: camera 100: unknown camera model id 18");
  std::memset(&bad[12], 0xff, 4);
  EXPECT_FALSE(colmap::parse_cameras_binary(bad, "c.bin", &cams, &error));
  EXPECT_EQ(error, "c.bin: byte 8: camera 100: unknown camera model id -1");
  // Truncated, trailing bytes, an absurd count, a NaN.
  EXPECT_FALSE(colmap::parse_cameras_binary(f.cameras.substr(0, f.cameras.size() - 1), "c.bin", &cams, &error));
  EXPECT_EQ(error, "c.bin: byte " + std::to_string(f.cameras.size() - 8) + ": the file ends inside a camera parameter");
  EXPECT_FALSE(colmap::parse_images_binary(f.images + "x", "i.bin", &ims, &error));
  EXPECT_EQ(error, "i.bin: byte " + std::to_string(f.images.size()) + ": 1 bytes after the last record");
  // A focal length that is not positive.
  bad = f.cameras;
  std::memset(&bad[32], 0, 8);  // the first camera's fx
  EXPECT_FALSE(colmap::parse_cameras_binary(bad, "c.bin", &cams, &error));
  EXPECT_EQ(error, "c.bin: byte 8: camera 100: OPENCV's fx must be positive, got 0");
  // Names the text format cannot hold: a line break, blanks only, a blank at either end.
  ASSERT_EQ(f.images.substr(72, 13), std::string("img_0000.png\0", 13));
  const std::pair<const char *, const char *> names[] = {{"img_\n000.png", "img_?000.png"},
                                                         {"            ", "            "},
                                                         {" img_000.png", " img_000.png"},
                                                         {"img_000.png\t", "img_000.png?"}};
  for (const auto &[name, shown] : names) {
    bad = f.images;
    bad.replace(72, 12, name);
    EXPECT_FALSE(colmap::parse_images_binary(bad, "i.bin", &ims, &error)) << name;
    EXPECT_EQ(error, std::string("i.bin: byte 8: image 10: the name \"") + shown +
                         "\" is empty, holds a line break or a NUL byte, or begins or ends with a blank, which the "
                         "model files cannot hold");
  }
  bad = f.points;
  bad[7] = 1;
  EXPECT_FALSE(colmap::parse_points_binary(bad, "p.bin", &pts, &error));
  EXPECT_EQ(error.rfind("p.bin: byte 0: the number of points is 72057594037927966, more than the ", 0), 0u) << error;
  bad = f.points;
  const double nan = std::nan("");
  std::memcpy(&bad[16], &nan, 8);
  EXPECT_FALSE(colmap::parse_points_binary(bad, "p.bin", &pts, &error));
  EXPECT_EQ(error, "p.bin: byte 16: a coordinate must be a finite number, got nan");
}

TEST(ColmapReader, ModelConsistency) {
  const std::string dir = temp_dir("consistency");
  const Scene s = make_scene(dir, euclidean::CameraKind::VaryingIntrinsicsDistortion, 4, 30);
  std::string error;
  colmap::Model m = s.model;
  m.images[1].camera_id = 5;
  EXPECT_FALSE(colmap::check_model(m, "dir", &error));
  EXPECT_EQ(error, "dir: image 13 uses camera 5, which cameras does not hold");
  m = s.model;
  m.points[0].track[0].point2d_idx = 0;  // the unmatched keypoint
  EXPECT_FALSE(colmap::check_model(m, "dir", &error));
  EXPECT_EQ(error.rfind("dir: point 1000 lists POINTS2D 0 of image ", 0), 0u) << error;
  m = s.model;
  m.points[0].track.pop_back();
  EXPECT_FALSE(colmap::check_model(m, "dir", &error));
  EXPECT_EQ(error, "dir: the tracks of points3D list " + std::to_string(s.problem.points.nprojections() - 1) +
                       " observations, the images name points in " +
                       std::to_string(s.problem.points.nprojections()));
  m = s.model;
  m.images[0].points[0].point3d_id = 1000;  // the unmatched keypoint now claims point 1000
  EXPECT_FALSE(colmap::check_model(m, "dir", &error));
  EXPECT_EQ(error, "dir: image 10 sees point 1000 twice: sba takes one observation per point and image");
}

// A model with every refined value changed, as a refinement would change it.
colmap::Model moved(colmap::Model m) {
  for (colmap::Camera &c : m.cameras) c.params[0] *= 1.01;
  for (colmap::Image &im : m.images) im.t[2] += 0.25;
  for (colmap::Point3D &p : m.points) p.xyz[0] += 0.5;
  return m;
}

// A model is replaced whole or not at all. Its files are written images, points3D, cameras:
// when the first cannot be written (a file size limit stands for a full disk here) or a later
// one cannot be made (a directory stands where it goes), the files of the model are as they
// were and no temporary is left.
TEST(ColmapWriter, ReplacesAModelWholeOrNotAtAll) {
  const std::string dir = temp_dir("whole_or_nothing");
  const Scene s = make_scene(dir, euclidean::CameraKind::VaryingIntrinsicsDistortion);
  const colmap::Model changed = moved(s.model);
  const std::string model = dir + "/m";
  std::string error;
  for (colmap::Encoding e : {colmap::Encoding::Text, colmap::Encoding::Binary}) {
    const std::vector<std::string> &names = e == colmap::Encoding::Text ? kTextFiles : kBinaryFiles;
    const std::string written_order[] = {names[1], names[2], names[0]};
    for (const std::string &failing : written_order) {
      SCOPED_TRACE(failing);
      std::filesystem::remove_all(model);
      ASSERT_TRUE(colmap::write_model(model, s.model, e, &error)) << error;
      const std::vector<std::string> others = [&] {
        std::vector<std::string> o = names;
        o.erase(std::find(o.begin(), o.end(), failing));
        return o;
      }();
      const std::vector<std::string> before = contents(model, others);
      bool written = true;
      if (failing == written_order[0]) {
        const std::size_t size = colmap::format_model(changed, e).images.size();
        rlimit old{};
        ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
        const rlimit low{static_cast<rlim_t>(size - 1), old.rlim_max};
        const auto handler = std::signal(SIGXFSZ, SIG_IGN);
        ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &low), 0);
        written = colmap::write_model(model, changed, e, &error);
        ::setrlimit(RLIMIT_FSIZE, &old);
        std::signal(SIGXFSZ, handler);
        EXPECT_EQ(error, model + "/" + failing + ": write failed: File too large");
      } else {
        std::filesystem::remove(model + "/" + failing);
        std::filesystem::create_directory(model + "/" + failing);
        written = colmap::write_model(model, changed, e, &error);
        EXPECT_EQ(error, model + "/" + failing + ": cannot open for writing: Is a directory");
      }
      EXPECT_FALSE(written);
      EXPECT_EQ(entries(model), names);
      EXPECT_TRUE(contents(model, others) == before);
    }
  }
}

// Writing a model in one format into a directory that holds the other replaces that one:
// its files go, so that no reader finds the stale model beside the new one.
TEST(ColmapWriter, WritingOneFormatRemovesTheOther) {
  const std::string dir = temp_dir("other_format");
  const Scene s = make_scene(dir, euclidean::CameraKind::VaryingIntrinsicsDistortion, 4, 30);
  const colmap::Model changed = moved(s.model);
  const std::string model = dir + "/m";
  std::string error;
  ASSERT_TRUE(colmap::write_model(model, s.model, colmap::Encoding::Text, &error)) << error;
  ASSERT_TRUE(colmap::write_model(model, changed, colmap::Encoding::Binary, &error)) << error;
  EXPECT_EQ(entries(model), kBinaryFiles);
  colmap::Model back;
  colmap::Encoding found;
  ASSERT_TRUE(colmap::read_model(model, &back, &found, &error)) << error;
  EXPECT_EQ(found, colmap::Encoding::Binary);
  expect_same(back, changed);
  ASSERT_TRUE(colmap::write_model(model, s.model, colmap::Encoding::Text, &error)) << error;
  EXPECT_EQ(entries(model), kTextFiles);
  ASSERT_TRUE(colmap::read_model(model, &back, &found, &error)) << error;
  EXPECT_EQ(found, colmap::Encoding::Text);
  expect_same(back, s.model);
}

// ---- rigs and frames (COLMAP 4) ----

// rigs and frames as pycolmap 4.2 writes them, from a model of three cameras and images 1..3:
// rig 1 of cameras 1 (the reference) and 2 (posed) and an IMU without a pose, rig 2 of an IMU
// (the reference) and camera 3, rig 5 of no sensor; frames 11..14, whose ids are not the images',
// two of them with an IMU's measurement, one of rig 5 with none.
const char *const kPycolmapRigs =
    "# Rig calib list with one line of data per calib:\n"
    "#   RIG_ID, NUM_SENSORS, REF_SENSOR_TYPE, REF_SENSOR_ID, SENSORS[] as (SENSOR_TYPE, SENSOR_ID, "
    "HAS_POSE, [QW, QX, QY, QZ, TX, TY, TZ])\n"
    "# Number of rigs: 3\n"
    "1 3 CAMERA 1 CAMERA 2 1 0.99844526913238008 -0 -0 -0.055740869630542866 0.058413656075265698 "
    "0.0048271336011196046 -0.0038852292537174815 IMU 7 0\n"
    "2 2 IMU 3 CAMERA 3 1 0.99432039012483786 -0 -0 -0.10642820012567247 -0.012789534076307769 "
    "0.070022004531221982 "
    "-0.049612876945207551\n"
    "5 0\n";
const char *const kPycolmapFrames =
    "# Frame list with one line of data per frame:\n"
    "#   FRAME_ID, RIG_ID, RIG_FROM_WORLD[QW, QX, QY, QZ, TX, TY, TZ], NUM_DATA_IDS, DATA_IDS[] as "
    "(SENSOR_TYPE, SENSOR_ID, DATA_ID)\n"
    "# Number of frames: 4\n"
    "11 1 0.53411548100981121 0.76424205614218732 0.36146193792600073 -0 8.8817841970012523e-16 "
    "-1.7763568394002505e-15 5.0000000000000018 2 CAMERA 1 1 IMU 7 1234567890123\n"
    "12 1 0.35094699128024437 -0.37423331358232942 0.85836218248274099 0 1.7763568394002505e-15 "
    "4.4408920985006262e-16 5.0000000000000018 1 CAMERA 2 2\n"
    "13 2 0.32976958296721531 -0.76612392269515395 -0.55163951746028761 0 -8.8817841970012523e-16 "
    "8.8817841970012523e-16 5.0000000000000018 2 CAMERA 3 3 IMU 3 5\n"
    "14 5 1 0 0 0 0 0 0 0\n";
// The same as pycolmap writes them in binary.
const char *const kPycolmapRigsHex =
    "030000000000000001000000030000000000000001000000000000000200000001ab9f387e43f3ef3f00000000000000"
    "80000000000000008088413a38118aacbf5d53f70c65e8ad3fda2534cf9dc5733f0036a192ead36fbf01000000070000"
    "000002000000020000000100000003000000000000000300000001e4a0aafe78d1ef3f00000000000000800000000000"
    "000080b272e9e6e03ebbbff7e6b53466318abf2843764bf6ecb13fe059e1e7db66a9bf0500000000000000";
const char *const kPycolmapFramesHex =
    "04000000000000000b00000001000000ae2e67597917e13fc178abc1ab74e83f690589403122d73f0000000000000080"
    "000000000000d03c000000000000e0bc0200000000001440020000000000000001000000010000000000000001000000"
    "07000000cb04fb711f0100000c0000000100000065688b5eea75d63f733aba4870f3d7bfac5ebcf7b377eb3f00000000"
    "00000000000000000000e03c000000000000c03c02000000000014400100000000000000020000000200000000000000"
    "0d00000002000000ebd283e1f11ad53fdc1515511684e8bf7f8ad5ea07a7e1bf0000000000000000000000000000d0bc"
    "000000000000d03c02000000000014400200000000000000030000000300000000000000010000000300000005000000"
    "000000000e00000005000000000000000000f03f00000000000000000000000000000000000000000000000000000000"
    "000000000000000000000000000000000000000000000000";

std::string from_hex(const std::string &hex) {
  std::string out;
  for (std::size_t k = 0; k + 1 < hex.size(); k += 2)
    out += static_cast<char>(std::stoi(hex.substr(k, 2), nullptr, 16));
  return out;
}

// The model of those rigs and frames: cameras and images 1..3 (image k of camera k), no
// points, every image at the identity pose.
colmap::Model rig_model() {
  colmap::Model m;
  m.cameras = {{1, colmap::kSimpleRadial, 1024, 768, {1280, 512, 384, 0.05}},
               {2, colmap::kPinhole, 1024, 768, {1280, 1281, 512, 384}},
               {3, colmap::kSimplePinhole, 1024, 768, {1279, 512, 384}}};
  for (std::uint32_t k = 1; k <= 3; ++k) {
    colmap::Image im;
    im.id = k;
    im.camera_id = k;
    im.name = "image" + std::to_string(k) + ".png";
    m.images.push_back(im);
  }
  std::string error;
  EXPECT_TRUE(colmap::parse_rigs_text(kPycolmapRigs, "rigs.txt", &m.rigs, &error)) << error;
  EXPECT_TRUE(colmap::parse_frames_text(kPycolmapFrames, "frames.txt", &m.frames, &error)) << error;
  m.has_rigs = true;
  return m;
}

TEST(ColmapRigs, PycolmapFilesRoundTripByteForByte) {
  const colmap::Model m = rig_model();
  ASSERT_EQ(m.rigs.size(), 3u);
  ASSERT_EQ(m.frames.size(), 4u);
  // Every field: the reference sensor first, a sensor without a pose, IMU sensors, a rig of no
  // sensor, the signs of zeros, frame ids that are not image ids, an IMU's 64-bit data id.
  const colmap::Rig &r1 = m.rigs[0];
  ASSERT_EQ(r1.sensors.size(), 3u);
  EXPECT_EQ(r1.id, 1u);
  EXPECT_TRUE(r1.sensors[0].sensor == (colmap::SensorId{colmap::SensorType::Camera, 1}));
  EXPECT_TRUE(r1.sensors[1].sensor == (colmap::SensorId{colmap::SensorType::Camera, 2}));
  EXPECT_TRUE(r1.sensors[1].has_pose);
  EXPECT_EQ(r1.sensors[1].sensor_from_rig.q[0], 0.99844526913238008);
  EXPECT_TRUE(std::signbit(r1.sensors[1].sensor_from_rig.q[1]));
  EXPECT_EQ(r1.sensors[1].sensor_from_rig.t[2], -0.0038852292537174815);
  EXPECT_TRUE(r1.sensors[2].sensor == (colmap::SensorId{colmap::SensorType::Imu, 7}));
  EXPECT_FALSE(r1.sensors[2].has_pose);
  EXPECT_TRUE(m.rigs[1].sensors[0].sensor == (colmap::SensorId{colmap::SensorType::Imu, 3}));
  EXPECT_EQ(m.rigs[2].id, 5u);
  EXPECT_TRUE(m.rigs[2].sensors.empty());
  EXPECT_EQ(m.frames[0].id, 11u);
  EXPECT_EQ(m.frames[0].rig_id, 1u);
  ASSERT_EQ(m.frames[0].data.size(), 2u);
  EXPECT_TRUE(m.frames[0].data[1].sensor == (colmap::SensorId{colmap::SensorType::Imu, 7}));
  EXPECT_EQ(m.frames[0].data[1].id, 1234567890123u);
  EXPECT_EQ(m.frames[2].data[0].id, 3u);
  EXPECT_EQ(m.frames[3].rig_id, 5u);
  EXPECT_TRUE(m.frames[3].data.empty());
  std::string error;
  EXPECT_TRUE(colmap::check_model(m, "dir", &error)) << error;

  // Text back to pycolmap's text, and to pycolmap's binary; its binary back to itself.
  const colmap::Files text = colmap::format_model(m, colmap::Encoding::Text);
  EXPECT_EQ(text.rigs, kPycolmapRigs);
  EXPECT_EQ(text.frames, kPycolmapFrames);
  const colmap::Files binary = colmap::format_model(m, colmap::Encoding::Binary);
  const std::string rigs_bin = from_hex(kPycolmapRigsHex), frames_bin = from_hex(kPycolmapFramesHex);
  EXPECT_EQ(binary.rigs, rigs_bin);
  EXPECT_EQ(binary.frames, frames_bin);
  colmap::Model b = m;
  ASSERT_TRUE(colmap::parse_rigs_binary(rigs_bin, "rigs.bin", &b.rigs, &error)) << error;
  ASSERT_TRUE(colmap::parse_frames_binary(frames_bin, "frames.bin", &b.frames, &error)) << error;
  const colmap::Files again = colmap::format_model(b, colmap::Encoding::Binary);
  EXPECT_EQ(again.rigs, rigs_bin);
  EXPECT_EQ(again.frames, frames_bin);
  EXPECT_EQ(colmap::format_model(b, colmap::Encoding::Text).frames, kPycolmapFrames);

  // The order of the file is kept (COLMAP writes its sets sorted; sbarefine writes back what
  // it read).
  const std::string unsorted = "5 0\n1 3 CAMERA 1 IMU 7 0 CAMERA 2 1 1 0 0 0 0.5 0 0\n";
  ASSERT_TRUE(colmap::parse_rigs_text(unsorted, "r", &b.rigs, &error)) << error;
  const std::string header(kPycolmapRigs, std::strstr(kPycolmapRigs, "# Number of rigs: ") + 18);
  EXPECT_EQ(colmap::format_model(b, colmap::Encoding::Text).rigs, header + "2\n" + unsorted);
}

TEST(ColmapRigs, TextErrors) {
  const Bad rigs[] = {
      {"1\n",
       "r.txt:1: expected RIG_ID NUM_SENSORS [REF_SENSOR_TYPE REF_SENSOR_ID] SENSORS[], found 1 values"},
      {"-1 0\n", "r.txt:1: RIG_ID must be an integer from 0 to 4294967295, got '-1'"},
      {"1 2 CAMERA 1\n", "r.txt:1: rig 1: the line ends inside sensor 2 of 2"},
      {"1 1 camera 1\n", "r.txt:1: SENSOR_TYPE must be CAMERA or IMU, got 'camera'"},
      {"1 2 CAMERA 1 GNSS 3 0\n", "r.txt:1: SENSOR_TYPE must be CAMERA or IMU, got 'GNSS'"},
      {"1 2 CAMERA 1 IMU 1 2\n", "r.txt:1: HAS_POSE must be an integer from 0 to 1, got '2'"},
      {"1 2 CAMERA 1 CAMERA 2 1 1 0 0\n", "r.txt:1: rig 1: the line ends inside the pose of sensor 2 of 2"},
      {"1 2 CAMERA 1 CAMERA 2 1 1 0 0 inf 0 0 0\n", "r.txt:1: QZ must be a finite number, got 'inf'"},
      {"1 2 CAMERA 1 CAMERA 2 1 0 0 0 0 1 2 3\n", "r.txt:1: rig 1: the quaternion of CAMERA 2 is zero"},
      {"1 1 CAMERA 1 1 1 0 0 0 0 0 0\n", "r.txt:1: rig 1: 8 values after its 1 sensors"},
      {"1 2 CAMERA 1 CAMERA 1 0\n", "r.txt:1: rig 1 lists CAMERA 1 twice"},
      {"# c\n1 1 CAMERA 1\n\n1 1 CAMERA 2\n", "r.txt:4: rig 1 appears twice"},
  };
  for (const Bad &b : rigs) {
    std::vector<colmap::Rig> out;
    std::string error;
    EXPECT_FALSE(colmap::parse_rigs_text(b.text, "r.txt", &out, &error)) << b.text;
    EXPECT_EQ(error, b.message);
  }
  const Bad frames[] = {
      {"1 1 1 0 0 0 0 0 0\n",
       "f.txt:1: expected FRAME_ID RIG_ID QW QX QY QZ TX TY TZ NUM_DATA_IDS DATA_IDS[], found 9 values"},
      {"1 1 1 0 0 0 0 0 0 2 CAMERA 1 1\n",
       "f.txt:1: frame 1 has NUM_DATA_IDS 2, followed by 3 values (SENSOR_TYPE SENSOR_ID DATA_ID each)"},
      {"1 1 1 0 0 0 0 0 0 99999999999\n",
       "f.txt:1: NUM_DATA_IDS must be an integer from 0 to 4294967295, got '99999999999'"},
      {"1 1 0 0 0 0 0 0 0 0\n", "f.txt:1: frame 1: the quaternion is zero"},
      {"1 1 1 0 0 0 0 nan 0 0\n", "f.txt:1: TY must be a finite number, got 'nan'"},
      {"1 1 1 0 0 0 0 0 0 1 LIDAR 1 1\n", "f.txt:1: SENSOR_TYPE must be CAMERA or IMU, got 'LIDAR'"},
      {"1 1 1 0 0 0 0 0 0 1 CAMERA 1 -1\n",
       "f.txt:1: DATA_ID must be an integer from 0 to 18446744073709551615, got '-1'"},
      {"1 1 1 0 0 0 0 0 0 3 IMU 7 5 CAMERA 7 5 IMU 7 5\n", "f.txt:1: frame 1 lists IMU 7 5 twice"},
      {"1 1 1 0 0 0 0 0 0 0\n2 1 1 0 0 0 0 0 0 0\n1 1 1 0 0 0 0 0 0 0\n", "f.txt:3: frame 1 appears twice"},
  };
  for (const Bad &b : frames) {
    std::vector<colmap::Frame> out;
    std::string error;
    EXPECT_FALSE(colmap::parse_frames_text(b.text, "f.txt", &out, &error)) << b.text;
    EXPECT_EQ(error, b.message);
  }
}

TEST(ColmapRigs, BinaryErrors) {
  const std::string rigs = from_hex(kPycolmapRigsHex), frames = from_hex(kPycolmapFramesHex);
  std::vector<colmap::Rig> r;
  std::vector<colmap::Frame> f;
  std::string error;
  // bytes with `size` bytes from `at` on replaced by value, little-endian.
  const auto with = [](std::string bytes, std::size_t at, std::uint64_t value, int size) {
    std::string le;
    for (int k = 0; k < size; ++k) le += static_cast<char>(value >> (8 * k));
    return bytes.replace(at, le.size(), le);
  };
  EXPECT_FALSE(colmap::parse_rigs_binary(rigs.substr(0, rigs.size() - 1), "r.bin", &r, &error));
  EXPECT_EQ(error, "r.bin: byte " + std::to_string(rigs.size() - 4) +
                       ": the file ends inside the number of sensors");
  EXPECT_FALSE(colmap::parse_rigs_binary(rigs + "x", "r.bin", &r, &error));
  EXPECT_EQ(error, "r.bin: byte " + std::to_string(rigs.size()) + ": 1 bytes after the last record");
  // Rig 1: its sensor count at byte 12, its reference sensor's type at 16, camera 2's HAS_POSE at 32.
  EXPECT_FALSE(colmap::parse_rigs_binary(with(rigs, 16, 2, 4), "r.bin", &r, &error));
  EXPECT_EQ(error, "r.bin: byte 16: rig 1: unknown sensor type 2");
  EXPECT_FALSE(colmap::parse_rigs_binary(with(rigs, 16, 0xffffffffu, 4), "r.bin", &r, &error));
  EXPECT_EQ(error, "r.bin: byte 16: rig 1: unknown sensor type -1");
  EXPECT_FALSE(colmap::parse_rigs_binary(with(rigs, 32, 2, 1), "r.bin", &r, &error));
  EXPECT_EQ(error, "r.bin: byte 24: rig 1: HAS_POSE of CAMERA 2 must be 0 or 1, got 2");
  EXPECT_FALSE(colmap::parse_rigs_binary(with(rigs, 12, 0xffffffffu, 4), "r.bin", &r, &error));
  EXPECT_EQ(error, "r.bin: byte 12: the number of sensors is 4294967295, more than the " +
                       std::to_string(rigs.size() - 16) + " bytes left can hold");
  EXPECT_FALSE(colmap::parse_rigs_binary(with(with(rigs, 24, 1, 4), 28, 7, 4), "r.bin", &r, &error));
  EXPECT_EQ(error, "r.bin: byte 8: rig 1 lists IMU 7 twice");
  EXPECT_FALSE(colmap::parse_rigs_binary(with(rigs, 8, 5, 4), "r.bin", &r, &error));
  EXPECT_EQ(error, "r.bin: byte " + std::to_string(rigs.size() - 8) + ": rig 5 appears twice");
  // Frame 11: its quaternion from byte 16, its data count at 72, its data from 76 (type, sensor,
  // id: 16 bytes each).
  EXPECT_FALSE(colmap::parse_frames_binary(frames.substr(0, frames.size() - 1), "f.bin", &f, &error));
  EXPECT_EQ(error, "f.bin: byte " + std::to_string(frames.size() - 4) +
                       ": the file ends inside the number of data ids");
  EXPECT_FALSE(colmap::parse_frames_binary(with(frames, 0, 1000, 8), "f.bin", &f, &error));
  EXPECT_EQ(error, "f.bin: byte 0: the number of frames is 1000, more than the " +
                       std::to_string(frames.size() - 8) + " bytes left can hold");
  EXPECT_FALSE(colmap::parse_frames_binary(with(frames, 76, 7, 4), "f.bin", &f, &error));
  EXPECT_EQ(error, "f.bin: byte 76: frame 11: unknown sensor type 7");
  EXPECT_FALSE(colmap::parse_frames_binary(with(frames, 72, 0x7fffffff, 4), "f.bin", &f, &error));
  EXPECT_EQ(error, "f.bin: byte 72: the number of data ids is 2147483647, more than the " +
                       std::to_string(frames.size() - 76) + " bytes left can hold");
  std::string zero = frames;
  std::fill_n(&zero[16], 32, '\0');
  EXPECT_FALSE(colmap::parse_frames_binary(zero, "f.bin", &f, &error));
  EXPECT_EQ(error, "f.bin: byte 8: frame 11: the quaternion is zero");
  EXPECT_FALSE(colmap::parse_frames_binary(with(with(with(frames, 92, 0, 4), 96, 1, 4), 100, 1, 8), "f.bin",
                                           &f, &error));
  EXPECT_EQ(error, "f.bin: byte 8: frame 11 lists CAMERA 1 1 twice");
  const double inf = INFINITY;
  std::string bad = frames;
  std::memcpy(&bad[48], &inf, 8);
  EXPECT_FALSE(colmap::parse_frames_binary(bad, "f.bin", &f, &error));
  EXPECT_EQ(error, "f.bin: byte 48: a translation component must be a finite number, got inf");
}

// What COLMAP 4 refuses to read (its reader throws), or reads into a model whose images have no
// pose, is refused by name.
TEST(ColmapRigs, ModelChecks) {
  const colmap::Model good = rig_model();
  struct Case {
    std::function<void(colmap::Model *)> edit;
    std::string message;
  };
  using colmap::SensorType;
  const Case cases[] = {
      {[](colmap::Model *m) { m->frames[0].rig_id = 9; },
       "dir: frame 11 is a pose of rig 9, which rigs does not hold"},
      {[](colmap::Model *m) { m->frames[1].data[0].id = 99; },
       "dir: frame 12 holds image 99 (CAMERA 2), which images does not hold"},
      {[](colmap::Model *m) { m->frames[1].data[0].id = 0x100000002ull; },
       "dir: frame 12 holds image 4294967298 (CAMERA 2), which images does not hold"},
      {[](colmap::Model *m) { m->frames[1].data[0].sensor.id = 3; },
       "dir: frame 12 holds data of CAMERA 3, which rig 1 does not hold"},
      {[](colmap::Model *m) { m->frames[0].data[1].sensor.id = 3; },
       "dir: frame 11 holds data of IMU 3, which rig 1 does not hold"},
      {[](colmap::Model *m) { m->images[1].camera_id = 1; },
       "dir: frame 12 holds image 2 as data of CAMERA 2, but the image's camera is 1"},
      {[](colmap::Model *m) { m->frames.erase(m->frames.begin() + 2); }, "dir: image 3 is in no frame"},
      {[](colmap::Model *m) {
         m->frames[1].data.push_back({{SensorType::Camera, 1}, 1});
       },
       "dir: image 1 is in frame 11 and in frame 12"},
      {[](colmap::Model *m) { m->rigs[1].sensors[1].sensor.id = 9; },
       "dir: rig 2 holds camera 9, which cameras does not hold"},
      {[](colmap::Model *m) {
         m->rigs[2].sensors.push_back({{SensorType::Camera, 1}, false, {}});
       },
       "dir: CAMERA 1 is a sensor of rig 1 and of rig 5: a sensor belongs to one rig"},
      {[](colmap::Model *m) {
         m->rigs[2].sensors.push_back({{SensorType::Imu, 3}, false, {}});
       },
       "dir: IMU 3 is a sensor of rig 2 and of rig 5: a sensor belongs to one rig"},
      {[](colmap::Model *m) { m->rigs[0].sensors[1].has_pose = false; },
       "dir: frame 12 holds image 2, whose camera 2 has no pose in rig 1 (HAS_POSE 0): the image's pose "
       "cannot "
       "be composed"},
      {[](colmap::Model *m) {
         m->frames[1].rig_from_world.t = {1.7e308, 1.7e308, 1.7e308};
       },
       "dir: frame 12: the pose of image 2, composed in rig 1, overflows"},
      {[](colmap::Model *m) {
         m->rigs[0].sensors[1].sensor_from_rig.q = {0, 0.6, 0, 0.3};
       },
       "dir: rig 1: the quaternion of CAMERA 2 has norm " + sbaformats::g17(std::sqrt(0.45)) +
           ": COLMAP composes its images' poses with it as written, which is a rotation only at norm 1"},
  };
  std::string error;
  for (const Case &c : cases) {
    colmap::Model m = good;
    c.edit(&m);
    EXPECT_FALSE(colmap::check_model(m, "dir", &error)) << c.message;
    EXPECT_EQ(error, c.message);
    // A model without rigs and frames has none to check.
    m.has_rigs = false;
    EXPECT_TRUE(colmap::check_model(m, "dir", &error)) << error;
  }
  // Within rounding of a unit norm, a quaternion is taken; a sensor without a pose that holds no
  // image, an IMU's, is too.
  colmap::Model m = good;
  for (double &v : m.rigs[0].sensors[1].sensor_from_rig.q) v *= 1 + 2e-11;
  EXPECT_TRUE(colmap::check_model(m, "dir", &error)) << error;
  for (double &v : m.rigs[0].sensors[1].sensor_from_rig.q) v *= 1 + 1e-10;
  EXPECT_FALSE(colmap::check_model(m, "dir", &error));
}

// pycolmap's poses of images 2 and 3 of rig_model, composed from the same rigs and frames
// (qw qx qy qz tx ty tz): what COLMAP 4 writes into the images file.
constexpr std::array<double, 7> kPycolmapPoses[] = {
    {0.35040136316000259, -0.32580562698845256, 0.87788775064583591, -0.019562090488183363,
     0.058413656075267516, 0.0048271336011198483, 4.9961147707462841},
    {0.32789662038726664, -0.8204826386597095, -0.46696923004372537, -0.035096783171394343,
     -0.012789534076308449, 0.070022004531223037, 4.950387123054794}};

// An image's pose is its frame's, as COLMAP 4 reads it, whatever images.txt says (image_poses):
// the reference sensor's the same bits, another sensor's composed (pycolmap's composition of
// the same files, to rounding). The inverse of the camera's pose in the rig composed with the
// image's pose gives the frame back.
TEST(ColmapRigs, ImagesTakeTheirFramesPoses) {
  const std::string dir = temp_dir("rig_poses");
  const colmap::Model m = rig_model();
  const auto &pycolmap = kPycolmapPoses;
  std::string error;
  for (colmap::Encoding e : {colmap::Encoding::Text, colmap::Encoding::Binary}) {
    const std::string out = dir + (e == colmap::Encoding::Text ? "/text" : "/binary");
    ASSERT_TRUE(colmap::write_model(out, m, e, &error)) << error;
    const std::string x = e == colmap::Encoding::Text ? ".txt" : ".bin";
    EXPECT_EQ(entries(out), (std::vector<std::string>{"cameras" + x, "frames" + x, "images" + x,
                                                      "points3D" + x, "rigs" + x}));
    colmap::Model back;
    ASSERT_TRUE(colmap::read_model(out, &back, nullptr, &error)) << error;
    EXPECT_TRUE(back.has_rigs);
    const std::vector<colmap::Pose> poses = colmap::image_poses(back);
    EXPECT_EQ(poses[0].q, m.frames[0].rig_from_world.q);
    EXPECT_EQ(poses[0].t, m.frames[0].rig_from_world.t);
    for (int k = 0; k < 2; ++k) {
      const colmap::Pose &im = poses[static_cast<std::size_t>(k + 1)];
      for (int c = 0; c < 4; ++c) EXPECT_NEAR(im.q[c], pycolmap[k][c], 1e-14) << k << c;
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(im.t[c], pycolmap[k][4 + c], 1e-14) << k << c;
    }
    // The rigs and frames as read.
    EXPECT_EQ(colmap::format_model(back, colmap::Encoding::Text).frames, kPycolmapFrames);
    const std::vector<colmap::ImagePlace> places = colmap::image_places(back);
    for (std::size_t i = 1; i < 3; ++i) {
      const colmap::ImagePlace &pl = places[i];
      const std::size_t f = pl.frame;
      back.frames[f].rig_from_world = colmap::frame_pose(
          poses[i], pl.sensor == 0 ? nullptr : &back.rigs[pl.rig].sensors[pl.sensor].sensor_from_rig);
      for (int c = 0; c < 4; ++c)
        EXPECT_NEAR(back.frames[f].rig_from_world.q[c], m.frames[f].rig_from_world.q[c], 1e-14) << f << c;
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(back.frames[f].rig_from_world.t[c], m.frames[f].rig_from_world.t[c], 1e-14) << f << c;
    }
  }
}

// An images file that holds the composed poses as COLMAP 4 wrote them (pycolmap's, which differ
// from read_model's own composition in their last bits) is read with those bits and written
// back the same bytes; one that holds another pose gets the frame's.
TEST(ColmapRigs, ComposedPosesAsWrittenComeBack) {
  const std::string dir = temp_dir("rig_poses_as_written");
  colmap::Model m = rig_model();
  m.images[0].q = m.frames[0].rig_from_world.q;
  m.images[0].t = m.frames[0].rig_from_world.t;
  for (std::size_t k = 0; k < 2; ++k) {
    std::copy_n(kPycolmapPoses[k].begin(), 4, m.images[k + 1].q.begin());
    std::copy_n(kPycolmapPoses[k].begin() + 4, 3, m.images[k + 1].t.begin());
  }
  // The library's own composition is not pycolmap's, bit for bit.
  const colmap::ImagePlace place = colmap::image_places(m)[2];
  const colmap::Pose composed = sbacameras::compose(m.rigs[place.rig].sensors[place.sensor].sensor_from_rig,
                                                    m.frames[place.frame].rig_from_world);
  EXPECT_NE(composed.q, m.images[2].q);
  std::string error;
  for (colmap::Encoding e : {colmap::Encoding::Text, colmap::Encoding::Binary}) {
    const std::string out = dir + (e == colmap::Encoding::Text ? "/text" : "/binary");
    const std::string images = out + (e == colmap::Encoding::Text ? "/images.txt" : "/images.bin");
    ASSERT_TRUE(colmap::write_model(out, m, e, &error)) << error;
    colmap::Model back;
    ASSERT_TRUE(colmap::read_model(out, &back, nullptr, &error)) << error;
    for (std::size_t k = 0; k < 3; ++k) {
      EXPECT_EQ(colmap::image_poses(back)[k].q, m.images[k].q) << k;
      EXPECT_EQ(colmap::image_poses(back)[k].t, m.images[k].t) << k;
    }
    EXPECT_EQ(colmap::format_model(back, e).images, read_file(images));
    // Moved by more than rounding, the images file's pose is not the frame's: the frame's wins.
    colmap::Model other = m;
    other.images[2].t[2] += 1e-12;
    ASSERT_TRUE(colmap::write_model(out, other, e, &error)) << error;
    ASSERT_TRUE(colmap::read_model(out, &back, nullptr, &error)) << error;
    EXPECT_EQ(colmap::image_poses(back)[2].q, composed.q);
    EXPECT_EQ(colmap::image_poses(back)[2].t, composed.t);
    EXPECT_EQ(colmap::image_poses(back)[1].t, m.images[1].t);
  }
}

// COLMAP's invalid id, 2^32 - 1 (kInvalidCameraId, kInvalidImageId, kInvalidRigId,
// kInvalidFrameId), which COLMAP refuses in a model: refused with its record in the files, text
// and binary, and in a model made in memory (what pysba writes).
TEST(ColmapReader, InvalidIdsAreRefused) {
  const std::string invalid = " 4294967295 is COLMAP's invalid id (";
  std::string error;
  std::vector<colmap::Camera> cams;
  EXPECT_FALSE(colmap::parse_cameras_text("1 PINHOLE 640 480 1 1 3 4\n4294967295 PINHOLE 640 480 1 1 3 4\n", "c.txt",
                                          &cams, &error));
  EXPECT_EQ(error, "c.txt:2: camera 4294967295: CAMERA_ID" + invalid + "kInvalidCameraId), which COLMAP refuses");
  std::vector<colmap::Image> ims;
  EXPECT_FALSE(colmap::parse_images_text("4294967295 1 0 0 0 0 0 0 1 a.png\n\n", "i.txt", &ims, &error));
  EXPECT_EQ(error, "i.txt:1: image 4294967295: IMAGE_ID" + invalid + "kInvalidImageId), which COLMAP refuses");
  EXPECT_FALSE(colmap::parse_images_text("1 1 0 0 0 0 0 0 4294967295 a.png\n\n", "i.txt", &ims, &error));
  EXPECT_EQ(error, "i.txt:1: image 1: CAMERA_ID" + invalid + "kInvalidCameraId), which COLMAP refuses");
  std::vector<colmap::Point3D> pts;
  EXPECT_FALSE(colmap::parse_points_text("1 0 0 0 1 2 3 0.5 4294967295 0\n", "p.txt", &pts, &error));
  EXPECT_EQ(error, "p.txt:1: point 1: IMAGE_ID" + invalid + "kInvalidImageId), which COLMAP refuses");
  std::vector<colmap::Rig> rigs;
  EXPECT_FALSE(colmap::parse_rigs_text("4294967295 1 CAMERA 1\n", "r.txt", &rigs, &error));
  EXPECT_EQ(error, "r.txt:1: rig 4294967295: RIG_ID" + invalid + "kInvalidRigId), which COLMAP refuses");
  std::vector<colmap::Frame> frames;
  EXPECT_FALSE(colmap::parse_frames_text("4294967295 1 1 0 0 0 0 0 0 0\n", "f.txt", &frames, &error));
  EXPECT_EQ(error, "f.txt:1: frame 4294967295: FRAME_ID" + invalid + "kInvalidFrameId), which COLMAP refuses");
  EXPECT_FALSE(colmap::parse_frames_text("1 4294967295 1 0 0 0 0 0 0 0\n", "f.txt", &frames, &error));
  EXPECT_EQ(error, "f.txt:1: frame 1: RIG_ID" + invalid + "kInvalidRigId), which COLMAP refuses");

  // Binary: the same records, named at their first byte.
  colmap::Model m = rig_model();
  m.points.push_back({5, {0, 0, 1}, {1, 2, 3}, 0.5, {{1, 0}}});
  m.images[0].points.push_back({1, 2, 5});
  ASSERT_TRUE(colmap::check_model(m, "m", &error)) << error;
  const colmap::Files f = colmap::format_model(m, colmap::Encoding::Binary);
  const auto with_invalid = [](std::string bytes, std::size_t at) { return bytes.replace(at, 4, 4, '\xff'); };
  EXPECT_FALSE(colmap::parse_cameras_binary(with_invalid(f.cameras, 8 + 56), "c.bin", &cams, &error));
  EXPECT_EQ(error, "c.bin: byte 64: camera 4294967295: CAMERA_ID" + invalid + "kInvalidCameraId), which COLMAP refuses");
  EXPECT_FALSE(colmap::parse_images_binary(with_invalid(f.images, 8), "i.bin", &ims, &error));
  EXPECT_EQ(error, "i.bin: byte 8: image 4294967295: IMAGE_ID" + invalid + "kInvalidImageId), which COLMAP refuses");
  EXPECT_FALSE(colmap::parse_images_binary(with_invalid(f.images, 8 + 60), "i.bin", &ims, &error));
  EXPECT_EQ(error, "i.bin: byte 8: image 1: CAMERA_ID" + invalid + "kInvalidCameraId), which COLMAP refuses");
  EXPECT_FALSE(colmap::parse_points_binary(with_invalid(f.points, 8 + 51), "p.bin", &pts, &error));
  EXPECT_EQ(error, "p.bin: byte 8: point 5: IMAGE_ID" + invalid + "kInvalidImageId), which COLMAP refuses");
  EXPECT_FALSE(colmap::parse_rigs_binary(with_invalid(f.rigs, 8), "r.bin", &rigs, &error));
  EXPECT_EQ(error, "r.bin: byte 8: rig 4294967295: RIG_ID" + invalid + "kInvalidRigId), which COLMAP refuses");
  EXPECT_FALSE(colmap::parse_frames_binary(with_invalid(f.frames, 8), "f.bin", &frames, &error));
  EXPECT_EQ(error, "f.bin: byte 8: frame 4294967295: FRAME_ID" + invalid + "kInvalidFrameId), which COLMAP refuses");
  EXPECT_FALSE(colmap::parse_frames_binary(with_invalid(f.frames, 12), "f.bin", &frames, &error));
  EXPECT_EQ(error, "f.bin: byte 8: frame 11: RIG_ID" + invalid + "kInvalidRigId), which COLMAP refuses");

  // A model made in memory, as pysba writes one: the record named.
  const struct {
    std::function<void(colmap::Model *)> edit;
    std::string message;
  } cases[] = {
      {[](colmap::Model *x) { x->cameras[1].id = 0xffffffffu; },
       "m: camera 4294967295: CAMERA_ID" + invalid + "kInvalidCameraId), which COLMAP refuses"},
      {[](colmap::Model *x) { x->images[2].id = 0xffffffffu; },
       "m: image 4294967295: IMAGE_ID" + invalid + "kInvalidImageId), which COLMAP refuses"},
      {[](colmap::Model *x) { x->images[2].camera_id = 0xffffffffu; },
       "m: image 3: CAMERA_ID" + invalid + "kInvalidCameraId), which COLMAP refuses"},
      {[](colmap::Model *x) { x->points[0].track[0].image_id = 0xffffffffu; },
       "m: point 5: IMAGE_ID" + invalid + "kInvalidImageId), which COLMAP refuses"},
      {[](colmap::Model *x) { x->rigs[0].id = 0xffffffffu; },
       "m: rig 4294967295: RIG_ID" + invalid + "kInvalidRigId), which COLMAP refuses"},
      {[](colmap::Model *x) { x->frames[1].id = 0xffffffffu; },
       "m: frame 4294967295: FRAME_ID" + invalid + "kInvalidFrameId), which COLMAP refuses"},
      {[](colmap::Model *x) { x->frames[1].rig_id = 0xffffffffu; },
       "m: frame 12: RIG_ID" + invalid + "kInvalidRigId), which COLMAP refuses"},
  };
  for (const auto &c : cases) {
    colmap::Model bad = m;
    c.edit(&bad);
    EXPECT_FALSE(colmap::check_records(bad, "m", &error)) << c.message;
    EXPECT_EQ(error, c.message);
  }
}

// COLMAP 4 refuses a model with one of the two files; so does read_model. Writing a model
// without rigs and frames removes those of this encoding; writing the other encoding removes
// all five files.
TEST(ColmapRigs, BothOrNeither) {
  const std::string dir = temp_dir("rig_files");
  const colmap::Model m = rig_model();
  colmap::Model plain = m;
  plain.has_rigs = false;
  std::string error;
  colmap::Model back;
  for (colmap::Encoding e : {colmap::Encoding::Text, colmap::Encoding::Binary}) {
    const std::string x = e == colmap::Encoding::Text ? ".txt" : ".bin";
    const std::string out = dir + "/m" + x;
    for (const char *file : {"rigs", "frames"}) {
      ASSERT_TRUE(colmap::write_model(out, m, e, &error)) << error;
      std::filesystem::remove(out + "/" + file + x);
      const std::string there = std::string(file) == "rigs" ? "frames" : "rigs";
      EXPECT_FALSE(colmap::read_model(out, &back, nullptr, &error));
      EXPECT_EQ(error, out + ": " + there + x + " without " + file + x +
                           ": COLMAP 4 refuses a model with one of the two");
    }
    ASSERT_TRUE(colmap::write_model(out, m, e, &error)) << error;
    ASSERT_TRUE(colmap::write_model(out, plain, e, &error)) << error;
    EXPECT_EQ(entries(out), (std::vector<std::string>{"cameras" + x, "images" + x, "points3D" + x}));
    ASSERT_TRUE(colmap::read_model(out, &back, nullptr, &error)) << error;
    EXPECT_FALSE(back.has_rigs);
    ASSERT_TRUE(colmap::write_model(out, m, e, &error)) << error;
    const colmap::Encoding other =
        e == colmap::Encoding::Text ? colmap::Encoding::Binary : colmap::Encoding::Text;
    const std::string y = e == colmap::Encoding::Text ? ".bin" : ".txt";
    ASSERT_TRUE(colmap::write_model(out, m, other, &error)) << error;
    EXPECT_EQ(entries(out), (std::vector<std::string>{"cameras" + y, "frames" + y, "images" + y,
                                                      "points3D" + y, "rigs" + y}));
  }
}

// ---- the images --hold-poses and --hold-poses-file name ----

// A model of images alone: all that an image list is resolved against.
colmap::Model images_named(const std::vector<std::pair<std::uint32_t, std::string>> &images) {
  colmap::Model m;
  for (const auto &[id, name] : images) {
    colmap::Image im;
    im.id = id;
    im.name = name;
    m.images.push_back(im);
  }
  return m;
}

// The IMAGE_IDs of the images that list names, in the model's order, or "error: " and why.
std::string held_ids(const colmap::Model &m, const std::string &list) {
  std::vector<char> held;
  const std::string why = colmap::parse_image_list(m, list, &held);
  if (!why.empty()) return "error: " + why;
  std::string out;
  for (std::size_t j = 0; j < held.size(); ++j)
    if (held[j]) out += (out.empty() ? "" : ",") + std::to_string(m.images[j].id);
  return out;
}

// An IMAGE_ID is plain decimal digits without a leading zero: no sign, no blank, nothing
// trimmed. Any other item is a NAME.
TEST(ColmapImageList, IdsArePlainDecimalDigits) {
  const colmap::Model m = images_named({{10, "img_0.png"}, {13, "img_1.png"}, {0, "zero.png"}});
  EXPECT_EQ(held_ids(m, "10"), "10");
  EXPECT_EQ(held_ids(m, "0,13"), "13,0");
  EXPECT_EQ(held_ids(m, "13,img_0.png,13"), "10,13");
  EXPECT_EQ(held_ids(m, "11"), "error: no image has the IMAGE_ID or NAME '11'");
  EXPECT_EQ(held_ids(m, "4294967306"), "error: no image has the IMAGE_ID or NAME '4294967306'");  // 2^32 + 10
  for (const std::string item : {" 10", "10 ", "+10", "010", "00", "-0", "1e1", "0x0a"})
    EXPECT_EQ(held_ids(m, item), "error: no image has the NAME '" + item + "'") << item;
  // A control character is quoted as \xHH: the message stays one line.
  EXPECT_EQ(held_ids(m, "10\r"), "error: no image has the NAME '10\\x0d'");
  EXPECT_EQ(held_ids(m, "\t13"), "error: no image has the NAME '\\x0913'");
}

// A NAME is matched exactly and names every image of that name. An item of digits is an
// IMAGE_ID first: the image named "10" is not named by "10" while image 10 exists (a file of
// names names it, see HoldPosesFile).
TEST(ColmapImageList, NamesAreMatchedExactly) {
  const colmap::Model m = images_named({{10, "img_0.png"}, {13, "10"}, {16, "010"}, {19, "+7"},
                                        {22, "a b.png"}, {25, "dup.png"}, {28, "dup.png"}, {31, "all"},
                                        {34, "12"}});
  EXPECT_EQ(held_ids(m, "10"), "10");
  EXPECT_EQ(held_ids(m, "12"), "34");  // no image has IMAGE_ID 12: the NAME
  EXPECT_EQ(held_ids(m, "010"), "16");
  EXPECT_EQ(held_ids(m, "+7"), "19");
  EXPECT_EQ(held_ids(m, "a b.png"), "22");
  EXPECT_EQ(held_ids(m, "dup.png"), "25,28");
  EXPECT_EQ(held_ids(m, "all"), "10,13,16,19,22,25,28,31,34");
  EXPECT_EQ(held_ids(m, "010,all"), "16,31");  // all means every image only as the whole list
  EXPECT_EQ(held_ids(m, "a b.png "), "error: no image has the NAME 'a b.png '");
  EXPECT_EQ(held_ids(m, "A B.PNG"), "error: no image has the NAME 'A B.PNG'");
}

// Items that say what they are (pysba's ints and strs) by the same rule: an IMAGE_ID names its
// image alone, a NAME every image of that name, digits or not.
TEST(ColmapImageList, ItemsOfAKnownKind) {
  const colmap::Model m = images_named({{10, "img_0.png"}, {13, "10"}, {25, "dup.png"}, {28, "dup.png"}});
  const colmap::ImageIndex index(m.images);
  std::vector<char> held(m.images.size(), 0);
  EXPECT_EQ(index.hold_id(10, &held), "");
  EXPECT_EQ(held, (std::vector<char>{1, 0, 0, 0}));
  EXPECT_EQ(index.hold_name("10", &held), "");
  EXPECT_EQ(index.hold_name("dup.png", &held), "");
  EXPECT_EQ(held, (std::vector<char>{1, 1, 1, 1}));
  EXPECT_EQ(index.hold_id(11, &held), "no image has the IMAGE_ID 11");
  EXPECT_EQ(index.hold_id(4294967306u, &held), "no image has the IMAGE_ID 4294967306");  // 2^32 + 10
  EXPECT_EQ(index.hold_name("img_0.png\n", &held), "no image has the NAME 'img_0.png\\x0a'");
  EXPECT_EQ(index.hold_text("10", &held), "");
}

TEST(ColmapImageList, EmptyItemsAreRefused) {
  const colmap::Model m = images_named({{10, "img_0.png"}, {13, "img_1.png"}});
  const std::string why = " is empty (two commas in a row, or a comma at an end)";
  EXPECT_EQ(held_ids(m, "10,,13"), "error: item 2" + why);
  EXPECT_EQ(held_ids(m, "10,13,"), "error: item 3" + why);
  EXPECT_EQ(held_ids(m, ",10"), "error: item 1" + why);
  EXPECT_EQ(held_ids(m, ","), "error: item 1" + why);
}

}  // namespace
