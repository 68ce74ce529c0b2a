// SPDX-License-Identifier: BSD-3-Clause
// The rules of a COLMAP record (lib/formats/colmap_check.h): each broken in a model made in
// memory gives its message from check_records, and the text and binary readers, on the files
// the writer makes of the same model, give that same message, each after its own place.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <regex>
#include <string>
#include <vector>

#include "formats/colmap_check.h"
#include "formats/colmap_io.h"
#include "scratch.h"

namespace colmap = sbaformats::colmap;

namespace {

constexpr std::uint32_t kInvalid = 0xffffffffu;

// Two cameras, two images in one frame of a rig of both cameras, a point seen in both: a model
// check_records and check_model take.
colmap::Model good_model() {
  colmap::Model m;
  m.cameras = {{1, colmap::kPinhole, 640, 480, {500, 501, 320, 240}},
               {2, colmap::kSimpleRadial, 640, 480, {450, 320, 240, 0.01}}};
  for (std::uint32_t k = 1; k <= 2; ++k) {
    colmap::Image im;
    im.id = k;
    im.camera_id = k;
    im.name = "image" + std::to_string(k) + ".png";
    im.points = {{100.5, 200.25, 7}};
    m.images.push_back(im);
  }
  colmap::Point3D p;
  p.id = 7;
  p.xyz = {0.5, -0.25, 4};
  p.track = {{1, 0}, {2, 0}};
  m.points = {p};
  colmap::RigSensor second{{colmap::SensorType::Camera, 2}, true, {}};
  second.sensor_from_rig.t = {0.1, 0, 0};
  m.rigs = {{1, {{{colmap::SensorType::Camera, 1}, false, {}}, second}}};
  colmap::Frame f;
  f.id = 11;
  f.rig_id = 1;
  f.rig_from_world.t = {0, 0, 1};
  f.data = {{{colmap::SensorType::Camera, 1}, 1}, {{colmap::SensorType::Camera, 2}, 2}};
  m.frames = {f};
  m.has_rigs = true;
  return m;
}

struct Case {
  const char *what;
  std::function<void(colmap::Model *)> edit;
  std::string message;  // after "model: "
};

void expect_refused(const std::vector<Case> &cases) {
  for (const Case &c : cases) {
    colmap::Model m = good_model();
    c.edit(&m);
    std::string error;
    EXPECT_FALSE(colmap::check_records(m, "model", &error)) << c.what;
    EXPECT_EQ(error, "model: " + c.message) << c.what;
  }
}

const std::string kInvalidIs = " 4294967295 is COLMAP's invalid id (";

TEST(ColmapCheck, GoodModelIsTaken) {
  std::string error;
  EXPECT_TRUE(colmap::check_records(good_model(), "model", &error)) << error;
  EXPECT_TRUE(colmap::check_model(good_model(), "model", &error)) << error;
}

TEST(ColmapCheck, CameraRules) {
  expect_refused({
      {"invalid id", [](colmap::Model *m) { m->cameras[0].id = kInvalid; },
       "camera 4294967295: CAMERA_ID" + kInvalidIs + "kInvalidCameraId), which COLMAP refuses"},
      {"model id 18", [](colmap::Model *m) { m->cameras[1].model = 18; }, "camera 2: unknown camera model id 18"},
      {"model id -1", [](colmap::Model *m) { m->cameras[1].model = -1; }, "camera 2: unknown camera model id -1"},
      {"too few", [](colmap::Model *m) { m->cameras[0].params.pop_back(); },
       "camera 1: PINHOLE has 4 parameters, found 3"},
      {"too many", [](colmap::Model *m) { m->cameras[1].params.push_back(0); },
       "camera 2: SIMPLE_RADIAL has 4 parameters, found 5"},
      {"f zero", [](colmap::Model *m) { m->cameras[1].params[0] = 0; },
       "camera 2: SIMPLE_RADIAL's f must be positive, got 0"},
      {"fy negative", [](colmap::Model *m) { m->cameras[0].params[1] = -501; },
       "camera 1: PINHOLE's fy must be positive, got -501"},
      {"aspect ratio", [](colmap::Model *m) { m->cameras[0].params = {1e-10, 1e308, 320, 240}; },
       "camera 1: PINHOLE's aspect ratio fy / fx overflows or underflows"},
      {"panorama", [](colmap::Model *m) { m->cameras[0] = {1, colmap::kEquirectangular, 640, 480, {640, -0.0}}; },
       "camera 1: EQUIRECTANGULAR's h must be positive, got -0"},
      {"twice", [](colmap::Model *m) { m->cameras[1].id = 1; }, "camera 1 appears twice"},
  });
}

TEST(ColmapCheck, ImageRules) {
  expect_refused({
      {"invalid id", [](colmap::Model *m) { m->images[1].id = kInvalid; },
       "image 4294967295: IMAGE_ID" + kInvalidIs + "kInvalidImageId), which COLMAP refuses"},
      {"invalid camera", [](colmap::Model *m) { m->images[1].camera_id = kInvalid; },
       "image 2: CAMERA_ID" + kInvalidIs + "kInvalidCameraId), which COLMAP refuses"},
      {"zero quaternion", [](colmap::Model *m) { m->images[0].q = {0, 0, 0, 0}; }, "image 1: the quaternion is zero"},
      {"twice", [](colmap::Model *m) { m->images[1].id = 1; }, "image 1 appears twice"},
  });
  const std::string cannot = "\" is empty, holds a line break or a NUL byte, or begins or ends with a blank, which "
                             "the model files cannot hold";
  const std::pair<std::string, std::string> names[] = {
      {"", ""}, {"a\nb.png", "a?b.png"}, {std::string("a\0b", 3), "a?b"}, {" a.png", " a.png"},
      {"a.png\t", "a.png?"}, {"a.png\r", "a.png?"}};
  for (const auto &[name, shown] : names)
    expect_refused({{"name", [name = name](colmap::Model *m) { m->images[0].name = name; },
                     "image 1: the name \"" + shown + cannot}});
}

TEST(ColmapCheck, PointRules) {
  expect_refused({
      {"-1", [](colmap::Model *m) { m->points[0].id = colmap::kNoPoint; }, "POINT3D_ID -1 is not an identifier"},
      {"invalid image", [](colmap::Model *m) { m->points[0].track[1].image_id = kInvalid; },
       "point 7: IMAGE_ID" + kInvalidIs + "kInvalidImageId), which COLMAP refuses"},
      {"twice", [](colmap::Model *m) { m->points.push_back(m->points[0]); }, "point 7 appears twice"},
  });
}

TEST(ColmapCheck, RigRules) {
  expect_refused({
      {"invalid id", [](colmap::Model *m) { m->rigs[0].id = kInvalid; },
       "rig 4294967295: RIG_ID" + kInvalidIs + "kInvalidRigId), which COLMAP refuses"},
      {"reference pose", [](colmap::Model *m) { m->rigs[0].sensors[0].has_pose = true; },
       "rig 1: its reference sensor CAMERA 1 has a pose in the rig, which the files cannot hold (it is the rig's "
       "origin)"},
      {"zero quaternion", [](colmap::Model *m) { m->rigs[0].sensors[1].sensor_from_rig.q = {0, 0, 0, 0}; },
       "rig 1: the quaternion of CAMERA 2 is zero"},
      {"sensor twice", [](colmap::Model *m) { m->rigs[0].sensors.push_back(m->rigs[0].sensors[1]); },
       "rig 1 lists CAMERA 2 twice"},
      {"twice", [](colmap::Model *m) { m->rigs.push_back({1, {}}); }, "rig 1 appears twice"},
  });
}

TEST(ColmapCheck, FrameRules) {
  expect_refused({
      {"invalid id", [](colmap::Model *m) { m->frames[0].id = kInvalid; },
       "frame 4294967295: FRAME_ID" + kInvalidIs + "kInvalidFrameId), which COLMAP refuses"},
      {"invalid rig", [](colmap::Model *m) { m->frames[0].rig_id = kInvalid; },
       "frame 11: RIG_ID" + kInvalidIs + "kInvalidRigId), which COLMAP refuses"},
      {"zero quaternion", [](colmap::Model *m) { m->frames[0].rig_from_world.q = {0, 0, 0, 0}; },
       "frame 11: the quaternion is zero"},
      {"data twice", [](colmap::Model *m) { m->frames[0].data.push_back(m->frames[0].data[0]); },
       "frame 11 lists CAMERA 1 1 twice"},
      {"twice", [](colmap::Model *m) { m->frames.push_back(m->frames[0]); }, "frame 11 appears twice"},
  });
}

// The first problem is reported: a record's own before the repeated ids of its kind, and the
// cameras before the images, the points, the rigs and the frames.
TEST(ColmapCheck, OrderOfProblems) {
  expect_refused({
      {"id before model",
       [](colmap::Model *m) {
         m->cameras[1].id = kInvalid;
         m->cameras[1].model = 18;
       },
       "camera 4294967295: CAMERA_ID" + kInvalidIs + "kInvalidCameraId), which COLMAP refuses"},
      {"own before twice",
       [](colmap::Model *m) {
         m->cameras[1].id = 1;
         m->cameras[1].params[0] = -1;
       },
       "camera 1: SIMPLE_RADIAL's f must be positive, got -1"},
      {"cameras first",
       [](colmap::Model *m) {
         m->frames[0].rig_from_world.q = {0, 0, 0, 0};
         m->cameras[0].params.clear();
       },
       "camera 1: PINHOLE has 4 parameters, found 0"},
      {"images before rigs",
       [](colmap::Model *m) {
         m->rigs[0].id = kInvalid;
         m->images[1].q = {0, 0, 0, 0};
       },
       "image 2: the quaternion is zero"},
  });
}

// ---- the readers give the same message ----

// The binary reader checks a camera's id and model id before it reads the parameters (their
// count is the model's), in check_records' order: the id first.
TEST(ColmapCheck, BinaryCameraHeadInCheckRecordsOrder) {
  std::string bytes = colmap::format_model(good_model(), colmap::Encoding::Binary).cameras;
  bytes.replace(8, 4, 4, '\xff');  // the first camera's id
  bytes[12] = 18;                   // its model id
  std::vector<colmap::Camera> cams;
  std::string error;
  EXPECT_FALSE(colmap::parse_cameras_binary(bytes, "c.bin", &cams, &error));
  EXPECT_EQ(error, "c.bin: byte 8: camera 4294967295: CAMERA_ID" + kInvalidIs +
                       "kInvalidCameraId), which COLMAP refuses");
  bytes.replace(8, 4, 4, '\0');
  EXPECT_FALSE(colmap::parse_cameras_binary(bytes, "c.bin", &cams, &error));
  EXPECT_EQ(error, "c.bin: byte 8: camera 0: unknown camera model id 18");
}

// error without the reader's place: "DIR/cameras.txt:4: " or "DIR/cameras.bin: byte 8: ",
// and *file the file named there ("cameras.txt").
std::string without_place(const std::string &error, std::string *file) {
  static const std::regex place(R"(^.*/([A-Za-z0-9]+\.(?:txt|bin))(?::[0-9]+|: byte [0-9]+): )");
  std::smatch m;
  if (!std::regex_search(error, m, place)) return "(no place) " + error;
  *file = m[1];
  return m.suffix();
}

// The same broken record, written by write_model in either encoding and read back: both
// readers refuse it with check_records' message, in the file of its kind.
TEST(ColmapCheck, TextAndBinaryReadersAgree) {
  const std::string dir = sbatest::scratch_dir() + "colmap_check_readers";
  const Case cases[] = {
      {"cameras.", [](colmap::Model *m) { m->cameras[0].params[0] = -500; },
       "camera 1: PINHOLE's fx must be positive, got -500"},
      {"cameras.", [](colmap::Model *m) { m->cameras[1].id = kInvalid; },
       "camera 4294967295: CAMERA_ID" + kInvalidIs + "kInvalidCameraId), which COLMAP refuses"},
      {"cameras.", [](colmap::Model *m) { m->cameras[1].id = 1; }, "camera 1 appears twice"},
      {"images.", [](colmap::Model *m) {
         m->has_rigs = false;  // the images file holds the image's own pose
         m->images[1].q = {0, 0, 0, 0};
       },
       "image 2: the quaternion is zero"},
      {"images.", [](colmap::Model *m) { m->images[0].camera_id = kInvalid; },
       "image 1: CAMERA_ID" + kInvalidIs + "kInvalidCameraId), which COLMAP refuses"},
      {"images.", [](colmap::Model *m) { m->images[1].id = 1; }, "image 1 appears twice"},
      {"points3D.", [](colmap::Model *m) { m->points[0].track[0].image_id = kInvalid; },
       "point 7: IMAGE_ID" + kInvalidIs + "kInvalidImageId), which COLMAP refuses"},
      {"points3D.", [](colmap::Model *m) { m->points.push_back(m->points[0]); }, "point 7 appears twice"},
      {"rigs.", [](colmap::Model *m) { m->rigs[0].sensors.push_back(m->rigs[0].sensors[1]); },
       "rig 1 lists CAMERA 2 twice"},
      {"rigs.", [](colmap::Model *m) { m->rigs.push_back({1, {}}); }, "rig 1 appears twice"},
      {"frames.", [](colmap::Model *m) { m->frames[0].rig_id = kInvalid; },
       "frame 11: RIG_ID" + kInvalidIs + "kInvalidRigId), which COLMAP refuses"},
      {"frames.", [](colmap::Model *m) { m->frames[0].data.push_back(m->frames[0].data[1]); },
       "frame 11 lists CAMERA 2 2 twice"},
  };
  for (const Case &c : cases) {
    colmap::Model m = good_model();
    c.edit(&m);
    for (colmap::Encoding e : {colmap::Encoding::Text, colmap::Encoding::Binary}) {
      const bool text = e == colmap::Encoding::Text;
      std::filesystem::remove_all(dir);
      std::string error, file;
      ASSERT_TRUE(colmap::write_model(dir, m, e, &error)) << error;
      colmap::Model back;
      EXPECT_FALSE(colmap::read_model(dir, &back, nullptr, &error)) << c.message;
      EXPECT_EQ(without_place(error, &file), c.message) << error;
      EXPECT_EQ(file, c.what + std::string(text ? "txt" : "bin")) << error;
    }
  }
}

}  // namespace
