// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: the COLMAP model parsers and the checks of a model as a whole. The first
// byte chooses (its value mod 12; mod 6 as the first six always were): 0..5 cameras, images,
// points3D as text, then the same as binary; 6..9 rigs and frames as text, then as binary;
// 10 and 11 a whole model, its five files one after the other, each ended by a line "%%" (10:
// text; 11: the same converted to binary first, so that the binary readers meet them whole).
// The rest is the content. What parses must format back to content that parses to the same
// records, and a text file's formatted form must be a fixed point; what parses keeps the
// readers' promises (positive focal lengths and panorama sizes, quaternions that normalize,
// names the text format can hold, no id that is COLMAP's invalid one). A model that check_model accepts keeps its promises too: every image in one frame,
// a finite pose composed for each, the frames' poses recovered from those (frame_pose),
// its files read back as the same model, and its problem (colmap::Problem) holding what a held image's
// pose holds, in a rig or not, whether the image sees points or not.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "cameras/colmap_camera.h"
#include "cameras/euclidean.h"
#include "formats/colmap_io.h"
#include "formats/colmap_problem.h"
#include "formats/colmap_sba.h"
#include "fuzz_common.h"

namespace colmap = sbaformats::colmap;
namespace euclidean = sbacameras::euclidean;

namespace {

using sbafuzz::require;

template <class T>
using Parser = bool (*)(const std::string &, const std::string &, std::vector<T> *, std::string *);

// Formats records of one file as the writer would, with the others empty.
template <class T, std::vector<T> colmap::Model::*Records, std::string colmap::Files::*File>
std::string format_file(const std::vector<T> &records, colmap::Encoding e) {
  colmap::Model m;
  m.*Records = records;
  return colmap::format_model(m, e).*File;
}
const auto format_cameras = format_file<colmap::Camera, &colmap::Model::cameras, &colmap::Files::cameras>;
const auto format_images = format_file<colmap::Image, &colmap::Model::images, &colmap::Files::images>;
const auto format_points = format_file<colmap::Point3D, &colmap::Model::points, &colmap::Files::points>;
const auto format_rigs = format_file<colmap::Rig, &colmap::Model::rigs, &colmap::Files::rigs>;
const auto format_frames = format_file<colmap::Frame, &colmap::Model::frames, &colmap::Files::frames>;

void require_rotation(const std::array<double, 4> &q, const std::string &what) {
  sbafuzz::require_rotation(euclidean::normalized_rotation({q[0], q[1], q[2], q[3]}), what);
}

// COLMAP's invalid id of cameras, images, rigs and frames, which the readers refuse.
constexpr std::uint32_t kInvalidId = 0xffffffffu;

// What the readers promise of what they accept, beyond its syntax.
void require_valid(const colmap::Camera &c) {
  require(c.id != kInvalidId, "accepted COLMAP's invalid camera id");
  // The focal lengths (f, or fx and fy) lead the parameters and are positive, and so is a
  // panorama's size.
  const int focals = sbacameras::colmap_camera::focal_count(c.model);
  for (int k = 0; k < focals; ++k)
    require(c.params[std::size_t(k)] > 0, "accepted a focal length that is not positive");
  if (c.model == colmap::kEquirectangular)
    require(c.params[0] > 0 && c.params[1] > 0, "accepted a panorama's size that is not positive");
}
void require_valid(const colmap::Image &im) {
  require(im.id != kInvalidId && im.camera_id != kInvalidId, "accepted COLMAP's invalid image or camera id");
  require_rotation(im.q, "an image's quaternion");
  require(!im.name.empty() && im.name.front() != ' ' && im.name.back() != ' ', "accepted a name text cannot hold");
}
void require_valid(const colmap::Point3D &p) {
  for (const colmap::TrackElement &e : p.track) require(e.image_id != kInvalidId, "accepted COLMAP's invalid image id");
}
void require_valid(const colmap::Rig &rig) {
  require(rig.id != kInvalidId, "accepted COLMAP's invalid rig id");
  for (std::size_t k = 1; k < rig.sensors.size(); ++k)
    if (rig.sensors[k].has_pose) require_rotation(rig.sensors[k].sensor_from_rig.q, "a sensor's quaternion");
  for (std::size_t j = 0; j < rig.sensors.size(); ++j)
    for (std::size_t k = 0; k < j; ++k)
      require(!(rig.sensors[j].sensor == rig.sensors[k].sensor), "accepted a sensor twice in a rig");
}
void require_valid(const colmap::Frame &f) {
  require(f.id != kInvalidId && f.rig_id != kInvalidId, "accepted COLMAP's invalid frame or rig id");
  require_rotation(f.rig_from_world.q, "a frame's quaternion");
  for (std::size_t j = 0; j < f.data.size(); ++j)
    for (std::size_t k = 0; k < j; ++k)
      require(!(f.data[j].sensor == f.data[k].sensor && f.data[j].id == f.data[k].id),
              "accepted a measurement twice in a frame");
}

template <class T>
void check(const std::string &content, Parser<T> parse, std::string (*format)(const std::vector<T> &, colmap::Encoding),
           colmap::Encoding e) {
  const std::string name = "fuzz-input";
  std::vector<T> records;
  std::string error;
  if (!parse(content, name, &records, &error)) {
    sbafuzz::check_error_line(error, name + ":");
    return;
  }
  for (const T &record : records) require_valid(record);
  const std::string once = format(records, e);
  std::vector<T> again;
  if (!parse(once, name, &again, &error)) sbafuzz::broken("the formatted records do not parse: " + error);
  require(format(again, e) == once, "formatting the records read back gives other content");
  // Both encodings carry the same values (names aside, which text trims).
  require(again.size() == records.size(), "a different number of records after the round trip");
}

// The parts of content, each ended by a line "%%" (the last part need not be).
std::vector<std::string> parts(const std::string &content) {
  std::vector<std::string> out(1);
  for (std::size_t pos = 0; pos < content.size();) {
    const std::size_t eol = std::min(content.find('\n', pos), content.size());
    const std::size_t next = std::min(eol + 1, content.size());
    if (content.compare(pos, eol - pos, "%%") == 0) out.emplace_back();
    else out.back().append(content, pos, next - pos);
    pos = next;
  }
  return out;
}

// The files of a model as parsed from its parts by the parsers of encoding e; false, with the
// error (a one-line message) in *error, when one does not parse.
bool parse_model(const std::vector<std::string> &f, colmap::Encoding e, colmap::Model *m,
                 std::string *error) {
  const bool text = e == colmap::Encoding::Text;
  const std::string name = "fuzz-model";
  const bool ok =
      (text ? colmap::parse_cameras_text : colmap::parse_cameras_binary)(f[0], name, &m->cameras, error) &&
      (text ? colmap::parse_images_text : colmap::parse_images_binary)(f[1], name, &m->images, error) &&
      (text ? colmap::parse_points_text : colmap::parse_points_binary)(f[2], name, &m->points, error) &&
      (!m->has_rigs ||
       ((text ? colmap::parse_rigs_text : colmap::parse_rigs_binary)(f[3], name, &m->rigs, error) &&
        (text ? colmap::parse_frames_text : colmap::parse_frames_binary)(f[4], name, &m->frames, error)));
  if (!ok) sbafuzz::check_error_line(*error, name + ":");
  return ok;
}

std::vector<std::string> files_of(const colmap::Files &f) {
  return {f.cameras, f.images, f.points, f.rigs, f.frames};
}

// Whether the binary reader takes the model's image names: the text reader takes a carriage
// return inside a name, which the binary reader refuses (as a line break); such a model is
// checked in text only.
bool binary_names(const colmap::Model &m) {
  return std::none_of(m.images.begin(), m.images.end(),
                      [](const colmap::Image &im) { return im.name.find('\r') != std::string::npos; });
}

// The largest magnitude of a pose's translation.
double size_of(const std::array<double, 3> &t) {
  return std::max({std::fabs(t[0]), std::fabs(t[1]), std::fabs(t[2])});
}

// The problem of an accepted model whose first image's pose is held (--hold-poses): that
// image's pose is held whether it sees points or not. In a rigged problem, every sba camera of
// its frame holds the frame's pose, and every one of its camera holds the camera's pose in the
// rig; otherwise its own sba camera, if it has one, holds its 6 pose parameters. It is counted
// held.
void check_held_first_image(const colmap::Model &m) {
  if (m.images.empty() || m.points.empty()) return;
  std::vector<char> held(m.images.size(), 0);
  held[0] = 1;
  colmap::Options options;
  options.constants.poses = held;
  colmap::Problem pr;
  std::string error;
  if (!colmap::Problem::build(m, options, "fuzz-model", &pr, &error)) {
    sbafuzz::check_error_line(error, "fuzz-model: ");
    return;
  }
  require(pr.counts().held_poses >= 1, "a held image is not counted held");
  const auto all = [](const char *f, int n) { return std::all_of(f, f + n, [](char c) { return c != 0; }); };
  const std::size_t cnp = static_cast<std::size_t>(pr.cnp());
  const std::vector<int> &images = pr.images();
  if (!pr.rigged()) {
    for (std::size_t j = 0; j < images.size(); ++j)
      if (images[j] == 0) require(all(&pr.cam_fixed()[j * cnp], 6), "a held image's pose is refined");
    return;
  }
  const std::vector<colmap::ImagePlace> places = colmap::image_places(m);
  for (std::size_t j = 0; j < images.size(); ++j) {
    const colmap::ImagePlace &pl = places[std::size_t(images[j])];
    const char *fixed = &pr.cam_fixed()[j * cnp];
    if (pl.frame == places[0].frame) require(all(fixed, 6), "the frame of a held image is refined");
    if (m.images[std::size_t(images[j])].camera_id == m.images[0].camera_id)
      require(all(fixed + 6, 6), "the pose in its rig of a held image's camera is refined");
  }
}

// A model accepted by check_model keeps check_model's promises: each image in one frame as data
// of its camera, in that frame's rig. Its images get finite poses from their frames; frames
// made from those poses give them back (the same bits for a rig's reference sensor); its files,
// in either encoding, read back to the same model.
void check_accepted(colmap::Model m) {
  if (m.has_rigs) {
    std::map<std::uint64_t, int> in_frames;
    std::map<std::uint32_t, const colmap::Rig *> rigs;
    for (const colmap::Rig &r : m.rigs) rigs[r.id] = &r;
    for (const colmap::Frame &f : m.frames) {
      require(rigs.count(f.rig_id) == 1, "accepted a frame of a rig that is not there");
      for (const colmap::DataId &d : f.data)
        if (d.sensor.type == colmap::SensorType::Camera) ++in_frames[d.id];
    }
    for (const colmap::Image &im : m.images)
      require(in_frames[im.id] == 1, "accepted an image not in one frame");
  }
  check_held_first_image(m);
  const std::vector<colmap::Pose> poses = colmap::image_poses(m);
  for (const colmap::Pose &pose : poses) {
    sbafuzz::require_finite(pose.t.begin(), pose.t.end(), "a composed translation");
    require_rotation(pose.q, "a composed quaternion");
  }
  if (m.has_rigs) {
    // Frames from the poses of the images alone in their frames, and the poses from those
    // frames again.
    std::map<std::uint64_t, char> alone;  // the images whose frame holds no other image
    for (const colmap::Frame &f : m.frames) {
      std::vector<std::uint64_t> ids;
      for (const colmap::DataId &d : f.data)
        if (d.sensor.type == colmap::SensorType::Camera) ids.push_back(d.id);
      if (ids.size() == 1) alone[ids[0]] = 1;
    }
    colmap::Model again = m;
    const std::vector<colmap::ImagePlace> places = colmap::image_places(m);
    for (std::size_t i = 0; i < m.images.size(); ++i) {
      if (!alone.count(m.images[i].id)) continue;
      const colmap::ImagePlace &pl = places[i];
      again.frames[pl.frame].rig_from_world =
          colmap::frame_pose(poses[i], pl.sensor == 0 ? nullptr : &m.rigs[pl.rig].sensors[pl.sensor].sensor_from_rig);
    }
    for (colmap::Image &im : again.images) im.q = {0, 0, 0, 0};  // composed anew, none kept
    const std::vector<colmap::Pose> again_poses = colmap::image_poses(again);
    for (std::size_t i = 0; i < m.images.size(); ++i) {
      const colmap::Pose &a = poses[i], &b = again_poses[i];
      double scale = 1 + size_of(a.t);
      for (const colmap::Rig &r : m.rigs)
        for (const colmap::RigSensor &s : r.sensors) scale += s.has_pose ? size_of(s.sensor_from_rig.t) : 0;
      if (!(scale < 1e100)) continue;  // translations that differences may overflow
      const euclidean::Quaternion qa = euclidean::normalized_rotation({a.q[0], a.q[1], a.q[2], a.q[3]}),
                                  qb = euclidean::normalized_rotation({b.q[0], b.q[1], b.q[2], b.q[3]});
      const double dq = std::max(
          {std::fabs(qa.w - qb.w), std::fabs(qa.x - qb.x), std::fabs(qa.y - qb.y), std::fabs(qa.z - qb.z)});
      double dt = 0;
      for (int k = 0; k < 3; ++k) dt = std::max(dt, std::fabs(a.t[k] - b.t[k]));
      require(dq <= 1e-12 && dt <= 1e-12 * scale, "frames made from the poses do not give them back");
    }
  }
  for (colmap::Encoding e : {colmap::Encoding::Text, colmap::Encoding::Binary}) {
    if (e == colmap::Encoding::Binary && !binary_names(m)) continue;
    const colmap::Files once = colmap::format_model(m, e);
    colmap::Model back;
    back.has_rigs = m.has_rigs;
    std::string error;
    if (!parse_model(files_of(once), e, &back, &error))
      sbafuzz::broken("a written model does not parse: " + error);
    if (!colmap::check_model(back, "fuzz-model", &error))
      sbafuzz::broken("a written model is refused: " + error);
    const colmap::Files twice = colmap::format_model(back, e);
    require(files_of(twice) == files_of(once), "a model read back formats to other files");
  }
}

void check_model(const std::string &content, bool binary) {
  // read_model refuses a text file that holds a NUL byte before any parser sees it.
  if (content.find('\0') != std::string::npos) return;
  std::vector<std::string> f = parts(content);
  colmap::Model m;
  m.has_rigs = f.size() >= 5;
  f.resize(5);
  std::string error;
  if (!parse_model(f, colmap::Encoding::Text, &m, &error)) return;
  if (binary && binary_names(m)) {
    colmap::Model b;
    b.has_rigs = m.has_rigs;
    if (!parse_model(files_of(colmap::format_model(m, colmap::Encoding::Binary)), colmap::Encoding::Binary,
                     &b, &error))
      sbafuzz::broken("the binary files of a text model do not parse: " + error);
    m = b;
  }
  if (!colmap::check_model(m, "fuzz-model", &error)) {
    sbafuzz::check_error_line(error, "fuzz-model: ");
    return;
  }
  check_accepted(m);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
  if (size == 0) return 0;
  const std::string content(reinterpret_cast<const char *>(data) + 1, size - 1);
  const colmap::Encoding text = colmap::Encoding::Text, binary = colmap::Encoding::Binary;
  switch (data[0] % 12) {
    case 0: check<colmap::Camera>(content, colmap::parse_cameras_text, format_cameras, text); break;
    case 1: check<colmap::Image>(content, colmap::parse_images_text, format_images, text); break;
    case 2: check<colmap::Point3D>(content, colmap::parse_points_text, format_points, text); break;
    case 3: check<colmap::Camera>(content, colmap::parse_cameras_binary, format_cameras, binary); break;
    case 4: check<colmap::Image>(content, colmap::parse_images_binary, format_images, binary); break;
    case 5:
      check<colmap::Point3D>(content, colmap::parse_points_binary, format_points, binary);
      break;
    case 6:
      check<colmap::Rig>(content, colmap::parse_rigs_text, format_rigs, text);
      break;
    case 7:
      check<colmap::Frame>(content, colmap::parse_frames_text, format_frames, text);
      break;
    case 8:
      check<colmap::Rig>(content, colmap::parse_rigs_binary, format_rigs, binary);
      break;
    case 9:
      check<colmap::Frame>(content, colmap::parse_frames_binary, format_frames, binary);
      break;
    default:
      check_model(content, data[0] % 12 == 11);
      break;
  }
  return 0;
}
