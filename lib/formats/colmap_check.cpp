// SPDX-License-Identifier: BSD-3-Clause
#include "formats/colmap_check.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <tuple>
#include <vector>

#include "formats/colmap_io_impl.h"
#include "formats/text_tokens.h"

namespace sbaformats::colmap {

namespace {

// COLMAP's invalid id of a camera, an image, a rig and a frame (its kInvalidCameraId,
// kInvalidImageId, kInvalidRigId, kInvalidFrameId: 2^32 - 1): COLMAP refuses a model that
// holds one.
constexpr std::uint32_t kInvalidId = 0xffffffffu;

// Why the field `what` (CAMERA_ID, IMAGE_ID, RIG_ID or FRAME_ID) cannot be kInvalidId:
// "CAMERA_ID 4294967295 is COLMAP's invalid id (kInvalidCameraId), which COLMAP refuses".
std::string invalid_id(const char *what) {
  static const char *const kNames[][2] = {{"CAMERA_ID", "kInvalidCameraId"},
                                          {"IMAGE_ID", "kInvalidImageId"},
                                          {"RIG_ID", "kInvalidRigId"},
                                          {"FRAME_ID", "kInvalidFrameId"}};
  std::string constant = "its invalid id";
  for (const auto &n : kNames)
    if (std::string(what) == n[0]) constant = n[1];
  return std::string(what) + " " + std::to_string(kInvalidId) + " is COLMAP's invalid id (" + constant +
         "), which COLMAP refuses";
}

// The zero quaternion, which is no rotation.
bool is_zero(const std::array<double, 4> &q) { return q[0] == 0 && q[1] == 0 && q[2] == 0 && q[3] == 0; }

// A focal length must be positive, and fy / fx (the aspect ratio sba keeps) a number neither
// infinite nor zero, and so must EQUIRECTANGULAR's w and h; otherwise the solve would meet an
// infinite aspect ratio or a mirrored image, far from here. The parameter count is the model's.
std::string bad_intrinsics(const Camera &c, const std::string &camera) {
  const ModelInfo &m = kModels[c.model];
  const std::string of = camera + m.name + "'s ";
  static const char *const kFocal[2][2] = {{"f", ""}, {"fx", "fy"}};
  for (int k = 0; k < m.focals; ++k) {
    const double f = c.params[static_cast<std::size_t>(k)];
    if (!(f > 0)) return of + kFocal[m.focals - 1][k] + " must be positive, got " + g17(f);
  }
  if (m.focals == 2) {
    const double ar = c.params[1] / c.params[0];
    if (!std::isfinite(ar) || ar == 0) return of + "aspect ratio fy / fx overflows or underflows";
  }
  // A panorama's size scales its pixels as a focal length does: one of no size, or a negative
  // one (a mirrored panorama), is no camera either.
  if (c.model == kEquirectangular)
    for (std::size_t k = 0; k < 2; ++k)
      if (!(c.params[k] > 0)) return of + (k == 0 ? "w" : "h") + " must be positive, got " + g17(c.params[k]);
  return {};
}

// A name the text format holds as it is: its reader takes the rest of the line, blanks at
// either end trimmed, and the binary format ends a name at a NUL byte.
bool text_holds_name(const std::string &name) {
  return !name.empty() && name.find_first_of(std::string("\r\n\0", 3)) == std::string::npos &&
         !is_blank(name.front()) && !is_blank(name.back());
}

SensorId sensor_of_key(std::uint64_t key) {
  return {static_cast<SensorType>(key >> 32), static_cast<std::uint32_t>(key)};
}

// "rig 1 lists CAMERA 2 twice", empty when no sensor repeats.
std::string repeated_sensor(const Rig &rig) {
  std::vector<std::uint64_t> keys;
  keys.reserve(rig.sensors.size());
  for (const RigSensor &s : rig.sensors) keys.push_back(sensor_key(s.sensor));
  std::sort(keys.begin(), keys.end());
  const auto twice = std::adjacent_find(keys.begin(), keys.end());
  if (twice == keys.end()) return {};
  return "rig " + std::to_string(rig.id) + " lists " + sensor_name(sensor_of_key(*twice)) + " twice";
}

// "frame 1 lists CAMERA 2 7 twice", empty when no measurement repeats.
std::string repeated_data(const Frame &frame) {
  std::vector<std::tuple<std::uint64_t, std::uint64_t>> keys;
  keys.reserve(frame.data.size());
  for (const DataId &d : frame.data) keys.emplace_back(sensor_key(d.sensor), d.id);
  std::sort(keys.begin(), keys.end());
  const auto twice = std::adjacent_find(keys.begin(), keys.end());
  if (twice == keys.end()) return {};
  return "frame " + std::to_string(frame.id) + " lists " + sensor_name(sensor_of_key(std::get<0>(*twice))) + " " +
         std::to_string(std::get<1>(*twice)) + " twice";
}

}  // namespace

std::string camera_head_problem(const Camera &c) {
  const std::string camera = "camera " + std::to_string(c.id) + ": ";
  if (c.id == kInvalidId) return camera + invalid_id("CAMERA_ID");
  if (!camera_model_name(c.model)) return camera + "unknown camera model id " + std::to_string(c.model);
  return {};
}

std::string camera_problem(const Camera &c) {
  if (std::string why = camera_head_problem(c); !why.empty()) return why;
  const std::string camera = "camera " + std::to_string(c.id) + ": ";
  const int np = camera_model_params(c.model);
  if (c.params.size() != static_cast<std::size_t>(np))
    return camera + camera_model_name(c.model) + " has " + std::to_string(np) + " parameters, found " +
           std::to_string(c.params.size());
  return bad_intrinsics(c, camera);
}

std::string image_problem(const Image &im) {
  const std::string image = "image " + std::to_string(im.id) + ": ";
  if (im.id == kInvalidId) return image + invalid_id("IMAGE_ID");
  if (im.camera_id == kInvalidId) return image + invalid_id("CAMERA_ID");
  if (is_zero(im.q)) return image + "the quaternion is zero";
  if (!text_holds_name(im.name))
    return image + "the name \"" + printable(im.name) +
           "\" is empty, holds a line break or a NUL byte, or begins or ends with a blank, which the model files "
           "cannot hold";
  return {};
}

std::string point_problem(const Point3D &p) {
  if (p.id == kNoPoint) return "POINT3D_ID -1 is not an identifier";
  for (const TrackElement &e : p.track)
    if (e.image_id == kInvalidId) return "point " + std::to_string(p.id) + ": " + invalid_id("IMAGE_ID");
  return {};
}

std::string rig_problem(const Rig &rig) {
  const std::string of_rig = "rig " + std::to_string(rig.id) + ": ";
  if (rig.id == kInvalidId) return of_rig + invalid_id("RIG_ID");
  if (!rig.sensors.empty() && rig.sensors.front().has_pose)
    return of_rig + "its reference sensor " + sensor_name(rig.sensors.front().sensor) +
           " has a pose in the rig, which the files cannot hold (it is the rig's origin)";
  for (const RigSensor &s : rig.sensors)
    if (s.has_pose && is_zero(s.sensor_from_rig.q))
      return of_rig + "the quaternion of " + sensor_name(s.sensor) + " is zero";
  return repeated_sensor(rig);
}

std::string frame_problem(const Frame &f) {
  const std::string frame = "frame " + std::to_string(f.id) + ": ";
  if (f.id == kInvalidId) return frame + invalid_id("FRAME_ID");
  if (f.rig_id == kInvalidId) return frame + invalid_id("RIG_ID");
  if (is_zero(f.rig_from_world.q)) return frame + "the quaternion is zero";
  return repeated_data(f);
}

std::string appears_twice(const char *what, std::uint64_t id) {
  return std::string(what) + " " + std::to_string(id) + " appears twice";
}

namespace {

// False at the first record that breaks a rule (problem), then at the first whose id an earlier
// one has: "WHERE" and the message.
template <class Record>
bool check_all(const std::vector<Record> &records, std::string (*problem)(const Record &), const char *what,
               const std::string &where, std::string *error) {
  for (const Record &r : records)
    if (std::string why = problem(r); !why.empty()) return fail(error, where + why);
  IdIndex ids(records.size());
  for (std::size_t k = 0; k < records.size(); ++k)
    if (!ids.insert(records[k].id, k)) return fail(error, where + appears_twice(what, records[k].id));
  return true;
}

}  // namespace

bool check_records(const Model &model, const std::string &name, std::string *error) {
  const std::string where = name + ": ";
  return check_all(model.cameras, camera_problem, "camera", where, error) &&
         check_all(model.images, image_problem, "image", where, error) &&
         check_all(model.points, point_problem, "point", where, error) &&
         check_all(model.rigs, rig_problem, "rig", where, error) &&
         check_all(model.frames, frame_problem, "frame", where, error);
}

}  // namespace sbaformats::colmap
