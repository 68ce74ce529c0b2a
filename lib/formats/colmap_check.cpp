// SPDX-License-Identifier: BSD-3-Clause
#include "formats/colmap_check.h"

#include <cstddef>
#include <cstdint>
#include <vector>

#include "formats/colmap_io_impl.h"

namespace sbaformats::colmap {

namespace {

// False at the first record whose id an earlier one has: "WHERE" "camera 3 appears twice".
template <class Record>
bool unique_ids(const std::vector<Record> &records, const char *what, const std::string &where,
                std::string *error) {
  IdIndex ids(records.size());
  for (std::size_t k = 0; k < records.size(); ++k)
    if (!ids.insert(records[k].id, k))
      return fail(error, where + what + " " + std::to_string(records[k].id) + " appears twice");
  return true;
}

bool check_cameras(const std::vector<Camera> &cameras, const std::string &where, std::string *error) {
  for (const Camera &c : cameras) {
    const std::string camera = "camera " + std::to_string(c.id) + ": ";
    if (c.id == kInvalidId) return fail(error, where + camera + invalid_id("CAMERA_ID"));
    if (!camera_model_name(c.model))
      return fail(error, where + camera + "unknown camera model id " + std::to_string(c.model));
    const int np = camera_model_params(c.model);
    if (c.params.size() != static_cast<std::size_t>(np))
      return fail(error, where + camera + camera_model_name(c.model) + " has " + std::to_string(np) +
                             " parameters, found " + std::to_string(c.params.size()));
    if (const std::string why = bad_intrinsics(c); !why.empty()) return fail(error, where + why);
  }
  return unique_ids(cameras, "camera", where, error);
}

// A name the text format holds as it is: its reader takes the rest of the line, blanks at
// either end trimmed, and the binary format ends a name at a NUL byte.
bool text_holds_name(const std::string &name) {
  return !name.empty() && name.find_first_of(std::string("\r\n\0", 3)) == std::string::npos &&
         !is_blank(name.front()) && !is_blank(name.back());
}

bool check_images(const std::vector<Image> &images, const std::string &where, std::string *error) {
  for (const Image &im : images) {
    const std::string image = "image " + std::to_string(im.id) + ": ";
    if (im.id == kInvalidId) return fail(error, where + image + invalid_id("IMAGE_ID"));
    if (im.camera_id == kInvalidId) return fail(error, where + image + invalid_id("CAMERA_ID"));
    if (is_zero(im.q)) return fail(error, where + image + "the quaternion is zero");
    if (!text_holds_name(im.name))
      return fail(error, where + image + "the name \"" + printable(im.name) +
                             "\" is empty, holds a line break or a NUL byte, or begins or ends with a blank, "
                             "which the model files cannot hold");
  }
  return unique_ids(images, "image", where, error);
}

bool check_points(const std::vector<Point3D> &points, const std::string &where, std::string *error) {
  for (const Point3D &p : points) {
    if (p.id == kNoPoint) return fail(error, where + "POINT3D_ID -1 is not an identifier");
    for (const TrackElement &e : p.track)
      if (e.image_id == kInvalidId)
        return fail(error, where + "point " + std::to_string(p.id) + ": " + invalid_id("IMAGE_ID"));
  }
  return unique_ids(points, "point", where, error);
}

bool check_rigs(const std::vector<Rig> &rigs, const std::string &where, std::string *error) {
  for (const Rig &rig : rigs) {
    if (rig.id == kInvalidId) return fail(error, where + "rig " + std::to_string(rig.id) + ": " + invalid_id("RIG_ID"));
    if (!rig.sensors.empty() && rig.sensors.front().has_pose)
      return fail(error, where + "rig " + std::to_string(rig.id) + ": its reference sensor " +
                             sensor_name(rig.sensors.front().sensor) +
                             " has a pose in the rig, which the files cannot hold (it is the rig's origin)");
    for (const RigSensor &s : rig.sensors)
      if (s.has_pose && is_zero(s.sensor_from_rig.q))
        return fail(error, where + "rig " + std::to_string(rig.id) + ": the quaternion of " +
                               sensor_name(s.sensor) + " is zero");
    if (const std::string why = repeated_sensor(rig); !why.empty()) return fail(error, where + why);
  }
  return unique_ids(rigs, "rig", where, error);
}

bool check_frames(const std::vector<Frame> &frames, const std::string &where, std::string *error) {
  for (const Frame &f : frames) {
    const std::string frame = "frame " + std::to_string(f.id) + ": ";
    if (f.id == kInvalidId) return fail(error, where + frame + invalid_id("FRAME_ID"));
    if (f.rig_id == kInvalidId) return fail(error, where + frame + invalid_id("RIG_ID"));
    if (is_zero(f.rig_from_world.q))
      return fail(error, where + "frame " + std::to_string(f.id) + ": the quaternion is zero");
    if (const std::string why = repeated_data(f); !why.empty()) return fail(error, where + why);
  }
  return unique_ids(frames, "frame", where, error);
}

}  // namespace

bool check_records(const Model &model, const std::string &name, std::string *error) {
  const std::string where = name + ": ";
  return check_cameras(model.cameras, where, error) && check_images(model.images, where, error) &&
         check_points(model.points, where, error) && check_rigs(model.rigs, where, error) &&
         check_frames(model.frames, where, error);
}

}  // namespace sbaformats::colmap
