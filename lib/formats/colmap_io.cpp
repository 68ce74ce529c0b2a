// SPDX-License-Identifier: BSD-3-Clause
// A COLMAP model as a whole: its camera models, the agreement of its files, the images' poses
// in their frames, and the files themselves, read and written in either encoding
// (colmap_text.cpp, colmap_binary.cpp).
#include "formats/colmap_io.h"

#include <sys/stat.h>

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <limits>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "cameras/euclidean.h"
#include "formats/colmap_io_impl.h"
#include "formats/output_file.h"
#include "formats/text_tokens.h"

namespace sbaformats::colmap {

std::string printable(const std::string &s) {
  std::string out;
  for (char c : s) {
    if (out.size() >= 40) return out + "...";
    out += (c >= 32 && c < 127) ? c : '?';
  }
  return out;
}

const char *camera_model_name(int model) { return sbacameras::colmap_camera::model_name(model); }

int camera_model_params(int model) { return sbacameras::colmap_camera::param_count(model); }

namespace {

// How far from 1 the squared norm of a sensor_from_rig quaternion may be. COLMAP composes an
// image's pose with the quaternion as written, not normalized, so that the translation it
// gives differs from the rotation's by about this much of its size: far below what the
// measurements can tell. COLMAP writes unit quaternions (to rounding), which pass, and so does
// one written to ten digits; one written by hand to a few is refused rather than read as
// another pose than COLMAP's.
constexpr double kUnitNormTolerance = 1e-10;

// The rigs and frames of a model agree with each other and with its cameras and images (see
// check_model): false with the first disagreement. Where each image is, once it is known that
// every image has one place, is find_places'.
bool check_rigs(const Model &model, const std::string &where, std::string *error) {
  constexpr std::size_t kNone = IdIndex::kNone;
  IdIndex cameras(model.cameras.size()), images(model.images.size()), rigs(model.rigs.size()), sensors;
  for (std::size_t k = 0; k < model.cameras.size(); ++k) cameras.insert(model.cameras[k].id, k);
  for (std::size_t k = 0; k < model.images.size(); ++k) images.insert(model.images[k].id, k);
  // Every sensor's rig and its place there, by its key; a sensor belongs to one rig.
  std::vector<std::pair<std::size_t, std::size_t>> sensor_at;
  for (std::size_t r = 0; r < model.rigs.size(); ++r) {
    const Rig &rig = model.rigs[r];
    rigs.insert(rig.id, r);
    for (std::size_t k = 0; k < rig.sensors.size(); ++k) {
      const SensorId &s = rig.sensors[k].sensor;
      if (s.type == SensorType::Camera && cameras.find(s.id) == kNone)
        return fail(error, where + "rig " + std::to_string(rig.id) + " holds camera " + std::to_string(s.id) +
                               ", which cameras does not hold");
      if (!sensors.insert(sensor_key(s), sensor_at.size()))
        return fail(error, where + sensor_name(s) + " is a sensor of rig " +
                               std::to_string(model.rigs[sensor_at[sensors.find(sensor_key(s))].first].id) +
                               " and of rig " + std::to_string(rig.id) + ": a sensor belongs to one rig");
      sensor_at.emplace_back(r, k);
    }
  }
  std::vector<std::size_t> frame_of(model.images.size(), kNone);
  for (std::size_t f = 0; f < model.frames.size(); ++f) {
    const Frame &fr = model.frames[f];
    const std::string frame = "frame " + std::to_string(fr.id);
    const std::size_t r = rigs.find(fr.rig_id);
    if (r == kNone)
      return fail(error, where + frame + " is a pose of rig " + std::to_string(fr.rig_id) +
                             ", which rigs does not hold");
    const Rig &rig = model.rigs[r];
    for (const DataId &d : fr.data) {
      const std::size_t s = sensors.find(sensor_key(d.sensor));
      if (s == kNone || sensor_at[s].first != r)
        return fail(error, where + frame + " holds data of " + sensor_name(d.sensor) + ", which rig " +
                               std::to_string(rig.id) + " does not hold");
      if (d.sensor.type != SensorType::Camera) continue;
      const std::size_t i = d.id <= 0xffffffffu ? images.find(d.id) : kNone;
      const std::string image = "image " + std::to_string(d.id);
      if (i == kNone)
        return fail(error, where + frame + " holds " + image + " (" + sensor_name(d.sensor) +
                               "), which images does not hold");
      if (model.images[i].camera_id != d.sensor.id)
        return fail(error, where + frame + " holds " + image + " as data of " + sensor_name(d.sensor) +
                               ", but the image's camera is " + std::to_string(model.images[i].camera_id));
      if (frame_of[i] != kNone)
        return fail(error, where + image + " is in frame " + std::to_string(model.frames[frame_of[i]].id) +
                               " and in " + frame);
      frame_of[i] = f;
      const std::size_t k = sensor_at[s].second;
      if (k == 0) continue;  // the reference sensor
      const RigSensor &sensor = rig.sensors[k];
      if (!sensor.has_pose)
        return fail(error, where + frame + " holds " + image + ", whose camera " +
                               std::to_string(d.sensor.id) + " has no pose in rig " + std::to_string(rig.id) +
                               " (HAS_POSE 0): the image's pose cannot be composed");
      const std::array<double, 4> &q = sensor.sensor_from_rig.q;
      const double norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
      if (!(std::fabs(norm2 - 1) <= kUnitNormTolerance))
        return fail(error,
                    where + "rig " + std::to_string(rig.id) + ": the quaternion of " + sensor_name(d.sensor) +
                        " has norm " + g17(std::sqrt(norm2)) +
                        ": COLMAP composes its images' poses with it as written, which is a rotation only at "
                        "norm 1");
      const Pose composed = sbacameras::compose(sensor.sensor_from_rig, fr.rig_from_world);
      if (!std::all_of(composed.t.begin(), composed.t.end(), [](double v) { return std::isfinite(v); }))
        return fail(error, where + frame + ": the pose of " + image + ", composed in rig " +
                               std::to_string(rig.id) + ", overflows");
    }
  }
  for (std::size_t i = 0; i < frame_of.size(); ++i)
    if (frame_of[i] == kNone)
      return fail(error, where + "image " + std::to_string(model.images[i].id) + " is in no frame");
  return true;
}

// Each image's place among the frames (one per Model::images): false when a frame names a rig,
// or a camera's measurement an image or a sensor of its rig, that the model does not hold, or
// when an image is in no frame or its camera has no pose in the rig, where no pose of it can be
// composed. In a model check_model accepted, every image has its one place; in another, an
// image in several frames is placed in the last.
bool find_places(const Model &model, std::vector<ImagePlace> *out) {
  constexpr std::size_t kNone = IdIndex::kNone;
  IdIndex images(model.images.size()), rigs(model.rigs.size());
  for (std::size_t k = 0; k < model.images.size(); ++k) images.insert(model.images[k].id, k);
  for (std::size_t k = 0; k < model.rigs.size(); ++k) rigs.insert(model.rigs[k].id, k);
  std::vector<ImagePlace> place(model.images.size(), ImagePlace{kNone, kNone, kNone});
  for (std::size_t f = 0; f < model.frames.size(); ++f) {
    const std::size_t r = rigs.find(model.frames[f].rig_id);
    if (r == kNone) return false;
    const std::vector<RigSensor> &sensors = model.rigs[r].sensors;
    for (const DataId &d : model.frames[f].data) {
      if (d.sensor.type != SensorType::Camera) continue;
      const std::size_t i = d.id <= 0xffffffffu ? images.find(d.id) : kNone;
      // A rig holds a handful of sensors: a look-up by key would cost more than the scan.
      const auto k = std::find_if(sensors.begin(), sensors.end(),
                                  [&](const RigSensor &s) { return s.sensor == d.sensor; });
      if (i == kNone || k == sensors.end() || (k != sensors.begin() && !k->has_pose)) return false;
      place[i] = {f, r, static_cast<std::size_t>(k - sensors.begin())};
    }
  }
  *out = std::move(place);
  return std::none_of(out->begin(), out->end(), [](const ImagePlace &p) { return p.frame == kNone; });
}

}  // namespace

namespace {

// How far, in units of the rounding, another composition of the same poses may be from
// compose's: each quaternion component to kComposeUlps eps, each translation component to
// kComposeUlps eps times the size of the translations composed. The operations on either side
// (a product of quaternions, a rotation, a sum) round a few eps each; a pose that differs more
// is another pose.
constexpr double kComposeUlps = 32;

// Whether the pose (q, t) is c, the pose compose gave of s and f, but for the rounding of
// another program's arithmetic (the sign of a quaternion aside: q and -q are one rotation).
bool same_but_rounding(const Pose &c, const Pose &s, const Pose &f, const std::array<double, 4> &q,
                       const std::array<double, 3> &t) {
  const double eps = kComposeUlps * std::numeric_limits<double>::epsilon();
  double d_plus = 0, d_minus = 0, dt = 0, size = 0;
  for (int k = 0; k < 4; ++k) {
    d_plus = std::max(d_plus, std::fabs(q[k] - c.q[k]));
    d_minus = std::max(d_minus, std::fabs(q[k] + c.q[k]));
  }
  for (int k = 0; k < 3; ++k) {
    dt = std::max(dt, std::fabs(t[k] - c.t[k]));
    size = std::max(size, std::fabs(f.t[k]) + std::fabs(s.t[k]));
  }
  return std::min(d_plus, d_minus) <= eps && dt <= eps * size;
}

}  // namespace

namespace {

std::vector<Pose> own_poses(const Model &model) {
  std::vector<Pose> poses(model.images.size());
  for (std::size_t i = 0; i < poses.size(); ++i) poses[i] = {model.images[i].q, model.images[i].t};
  return poses;
}

}  // namespace

std::vector<Pose> image_poses(const Model &model, const std::vector<ImagePlace> &places) {
  if (!model.has_rigs) return own_poses(model);
  std::vector<Pose> poses(model.images.size());
  for (std::size_t i = 0; i < places.size(); ++i) {
    const Image &im = model.images[i];
    const Pose &frame = model.frames[places[i].frame].rig_from_world;
    if (places[i].sensor == 0) {  // the rig's reference sensor
      poses[i] = frame;
      continue;
    }
    const Pose &sensor = model.rigs[places[i].rig].sensors[places[i].sensor].sensor_from_rig;
    const Pose p = sbacameras::compose(sensor, frame);
    // The images file's own bits, where they are this pose as COLMAP's arithmetic composed it:
    // what nothing changed is written back as it was read.
    poses[i] = same_but_rounding(p, sensor, frame, im.q, im.t) ? Pose{im.q, im.t} : p;
  }
  return poses;
}

std::vector<Pose> image_poses(const Model &model) {
  std::vector<ImagePlace> places;
  if (!model.has_rigs || !find_places(model, &places)) return own_poses(model);
  return image_poses(model, places);
}

DepthFilter filter_negative_depth(Model *model) {
  DepthFilter out;
  const std::vector<Pose> poses = image_poses(*model);
  std::unordered_map<std::uint64_t, std::size_t> point_at;
  for (std::size_t k = 0; k < model->points.size(); ++k) point_at.emplace(model->points[k].id, k);
  std::unordered_set<std::uint64_t> touched;  // the points that lost an observation: COLMAP
                                              // deletes a point as its track falls below two
  for (std::size_t i = 0; i < model->images.size(); ++i) {
    Image &im = model->images[i];
    const Pose &pose = poses[i];
    // The third row of R(q), q normalized (of any size, as a pose's quaternion is read).
    double R[9];
    sbacameras::euclidean::rotation_matrix(
        sbacameras::euclidean::normalized_rotation({pose.q[0], pose.q[1], pose.q[2], pose.q[3]}), R);
    const double *r = R + 6;
    for (std::size_t k = 0; k < im.points.size(); ++k) {
      Point2D &obs = im.points[k];
      if (obs.point3d_id == kNoPoint) continue;
      Point3D &pt = model->points[point_at.at(obs.point3d_id)];
      const double depth = r[0] * pt.xyz[0] + r[1] * pt.xyz[1] + r[2] * pt.xyz[2] + pose.t[2];
      if (depth >= std::numeric_limits<double>::epsilon()) continue;
      const TrackElement e{im.id, static_cast<std::uint32_t>(k)};
      out.observations.push_back(e);
      pt.track.erase(std::find_if(pt.track.begin(), pt.track.end(), [&](const TrackElement &t) {
        return t.image_id == e.image_id && t.point2d_idx == e.point2d_idx;
      }));
      obs.point3d_id = kNoPoint;
      touched.insert(pt.id);
    }
  }
  if (out.observations.empty()) return out;
  std::unordered_map<std::uint32_t, std::size_t> image_at;
  for (std::size_t i = 0; i < model->images.size(); ++i) image_at.emplace(model->images[i].id, i);
  const auto last = std::remove_if(model->points.begin(), model->points.end(), [&](const Point3D &pt) {
    if (pt.track.size() >= 2 || touched.count(pt.id) == 0) return false;
    for (const TrackElement &e : pt.track)
      model->images[image_at.at(e.image_id)].points[e.point2d_idx].point3d_id = kNoPoint;
    return true;
  });
  out.points = static_cast<std::size_t>(model->points.end() - last);
  model->points.erase(last, model->points.end());
  return out;
}

Pose frame_pose(const Pose &pose, const Pose *sensor_from_rig) {
  return sensor_from_rig ? sbacameras::between(*sensor_from_rig, pose) : pose;
}

std::vector<ImagePlace> image_places(const Model &model) {
  std::vector<ImagePlace> places;
  const bool placed = find_places(model, &places);
  assert(placed);
  (void)placed;
  return places;
}

bool check_model(const Model &model, const std::string &name, std::string *error) {
  const std::string where = name + ": ";
  constexpr std::size_t kNone = IdIndex::kNone;
  IdIndex cameras(model.cameras.size()), images(model.images.size()), points(model.points.size());
  for (std::size_t k = 0; k < model.cameras.size(); ++k) cameras.insert(model.cameras[k].id, k);
  for (std::size_t k = 0; k < model.points.size(); ++k) points.insert(model.points[k].id, k);
  for (std::size_t i = 0; i < model.images.size(); ++i) {
    const Image &im = model.images[i];
    images.insert(im.id, i);
    if (cameras.find(im.camera_id) == kNone)
      return fail(error, where + "image " + std::to_string(im.id) + " uses camera " + std::to_string(im.camera_id) +
                             ", which cameras does not hold");
  }
  // Each observation that names a point is claimed by exactly one track element. The marks
  // below stand for per-image and per-track sets, without an allocation for each:
  // seen_by[p] is 1 + the last image that saw point p, listed_by[i] 1 + the last point whose
  // track listed image i.
  std::size_t observations = 0;
  std::vector<std::size_t> seen_by(model.points.size(), 0);
  for (std::size_t i = 0; i < model.images.size(); ++i) {
    const Image &im = model.images[i];
    for (std::size_t k = 0; k < im.points.size(); ++k) {
      const std::uint64_t pid = im.points[k].point3d_id;
      if (pid == kNoPoint) continue;
      ++observations;
      const std::size_t p = points.find(pid);
      if (p == kNone)
        return fail(error, where + "image " + std::to_string(im.id) + " POINTS2D " + std::to_string(k) +
                               " names point " + std::to_string(pid) + ", which points3D does not hold");
      if (seen_by[p] == i + 1)
        return fail(error, where + "image " + std::to_string(im.id) + " sees point " + std::to_string(pid) +
                               " twice: sba takes one observation per point and image");
      seen_by[p] = i + 1;
    }
  }
  std::size_t elements = 0;
  std::vector<std::size_t> listed_by(model.images.size(), 0);
  for (std::size_t j = 0; j < model.points.size(); ++j) {
    const Point3D &p = model.points[j];
    if (p.track.empty()) return fail(error, where + "point " + std::to_string(p.id) + " has an empty track");
    for (const TrackElement &e : p.track) {
      const std::size_t i = images.find(e.image_id);
      if (i == kNone)
        return fail(error, where + "point " + std::to_string(p.id) + " is seen in image " +
                               std::to_string(e.image_id) + ", which images does not hold");
      const Image &im = model.images[i];
      if (e.point2d_idx >= im.points.size())
        return fail(error, where + "point " + std::to_string(p.id) + ": POINT2D_IDX " +
                               std::to_string(e.point2d_idx) + " is out of range for image " +
                               std::to_string(im.id) + " (" + std::to_string(im.points.size()) + " POINTS2D)");
      if (im.points[e.point2d_idx].point3d_id != p.id)
        return fail(error, where + "point " + std::to_string(p.id) + " lists POINTS2D " +
                               std::to_string(e.point2d_idx) + " of image " + std::to_string(im.id) +
                               ", which does not name it");
      // No image sees a point twice (checked above), so an image listed twice in a track is
      // the same observation listed twice.
      if (listed_by[i] == j + 1)
        return fail(error, where + "point " + std::to_string(p.id) + " lists POINTS2D " +
                               std::to_string(e.point2d_idx) + " of image " + std::to_string(im.id) + " twice");
      listed_by[i] = j + 1;
      ++elements;
    }
  }
  // Every element points back (checked above) and none repeats, so equal counts mean every
  // observation is listed.
  if (elements != observations)
    return fail(error, where + "the tracks of points3D list " + std::to_string(elements) +
                           " observations, the images name points in " + std::to_string(observations));
  return !model.has_rigs || check_rigs(model, where, error);
}

// ---- files ----

bool read_rest(std::FILE *f, const std::string &path, bool text, std::string *out, std::string *error) {
  // Straight into *out, in what its capacity leaves (read_whole_file reserves the file's size),
  // or 64 KiB at a time past it.
  for (;;) {
    const std::size_t old = out->size();
    const std::size_t room = std::max<std::size_t>(out->capacity() - old, std::size_t{1} << 16);
    out->resize(old + room);
    const std::size_t got = std::fread(&(*out)[old], 1, room, f);
    out->resize(old + got);
    if (text && std::memchr(out->data() + old, '\0', got)) return fail(error, path + ": a NUL byte: not a text file");
    if (got < room) break;
  }
  if (std::ferror(f)) return fail(error, path + ": read error");
  return true;
}

bool read_whole_file(const std::string &path, bool text, std::string *out, std::string *error) {
  std::FILE *f = std::fopen(path.c_str(), "rb");
  if (!f) return fail(error, path + ": cannot open: " + std::strerror(errno));
  // fopen opens a directory for reading, whose reading then fails without saying why.
  struct stat st {};
  if (::fstat(fileno(f), &st) == 0 && S_ISDIR(st.st_mode)) {
    std::fclose(f);
    return fail(error, path + ": is a directory");
  }
  std::string data;
  // One byte more than the size, so that the end of the file is seen without growing data.
  if (S_ISREG(st.st_mode) && st.st_size > 0) data.reserve(static_cast<std::size_t>(st.st_size) + 1);
  const bool read = read_rest(f, path, text, &data, error);
  std::fclose(f);
  if (!read) return false;
  *out = std::move(data);
  return true;
}

namespace {

// A model's files, in the order they are written and renamed onto their names: the cameras
// file last. A reader takes a directory's model by its cameras file (binary first): while a
// rewrite renames its files, the directory is read as the model it held until the new cameras
// file is in place, and a rename that fails before leaves that model readable (when the new
// model has the other encoding, whole; otherwise with the files already renamed refined, as
// the old ones held the same ids).
struct ModelFile {
  const char *name;
  std::string Files::*content;
  bool rig_file;  // rigs or frames: written only for a model that has them
};
constexpr ModelFile kModelFiles[] = {{"images", &Files::images, false},
                                     {"points3D", &Files::points, false},
                                     {"rigs", &Files::rigs, true},
                                     {"frames", &Files::frames, true},
                                     {"cameras", &Files::cameras, false}};

const char *extension(Encoding encoding) { return encoding == Encoding::Text ? ".txt" : ".bin"; }

std::string slashed(const std::string &dir) { return dir.empty() || dir.back() == '/' ? dir : dir + "/"; }

// A model's file: a regular file, or its reading would never end (/dev/zero) or fail
// without saying why (a directory).
bool read_model_file(const std::string &path, bool text, std::string *out, std::string *error) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return fail(error, path + ": cannot open: " + std::strerror(errno));
  if (S_ISDIR(st.st_mode)) return fail(error, path + ": is a directory");
  if (!S_ISREG(st.st_mode)) return fail(error, path + ": not a regular file");
  return read_whole_file(path, text, out, error);
}

template <class T>
using Parser = bool (*)(const std::string &, const std::string &, std::vector<T> *, std::string *);

// The records of the model's file at path.
template <class T>
bool read_records(const std::string &path, bool text, Parser<T> parse, std::vector<T> *out,
                  std::string *error) {
  std::string content;
  return read_model_file(path, text, &content, error) && parse(content, path, out, error);
}

// Whether anything is at path (*there), false with "PATH: cannot open: REASON" when that cannot
// be told (a symbolic link loop, a directory that cannot be searched).
bool is_there(const std::string &path, bool *there, std::string *error) {
  struct stat st {};
  *there = ::stat(path.c_str(), &st) == 0;
  if (*there || errno == ENOENT || errno == ENOTDIR) return true;
  return fail(error, path + ": cannot open: " + std::strerror(errno));
}

}  // namespace

bool has_model(const std::string &dir, Encoding encoding) {
  struct stat st {};
  return ::stat((slashed(dir) + "cameras" + extension(encoding)).c_str(), &st) == 0;
}

bool model_encoding(const std::string &dir, Encoding *out, std::string *error) {
  for (Encoding e : {Encoding::Binary, Encoding::Text}) {
    bool there;
    if (!is_there(slashed(dir) + "cameras" + extension(e), &there, error)) return false;
    if (there) {
      *out = e;
      return true;
    }
  }
  return fail(error, dir + ": no COLMAP model (cameras.txt or cameras.bin)");
}

bool read_model(const std::string &dir, Model *out, Encoding *encoding, std::string *error) {
  Encoding enc;
  if (!model_encoding(dir, &enc, error)) return false;
  const bool text = enc == Encoding::Text;
  const auto path = [&](const char *file) { return slashed(dir) + file + extension(enc); };
  Model m;
  if (!read_records(path("cameras"), text, text ? parse_cameras_text : parse_cameras_binary, &m.cameras,
                    error) ||
      !read_records(path("images"), text, text ? parse_images_text : parse_images_binary, &m.images, error) ||
      !read_records(path("points3D"), text, text ? parse_points_text : parse_points_binary, &m.points, error))
    return false;
  bool rigs, frames;
  if (!is_there(path("rigs"), &rigs, error) || !is_there(path("frames"), &frames, error)) return false;
  if (rigs != frames) {
    const std::string one = std::string(rigs ? "rigs" : "frames") + extension(enc);
    const std::string other = std::string(rigs ? "frames" : "rigs") + extension(enc);
    return fail(error,
                dir + ": " + one + " without " + other + ": COLMAP 4 refuses a model with one of the two");
  }
  if (rigs &&
      (!read_records(path("rigs"), text, text ? parse_rigs_text : parse_rigs_binary, &m.rigs, error) ||
       !read_records(path("frames"), text, text ? parse_frames_text : parse_frames_binary, &m.frames, error)))
    return false;
  m.has_rigs = rigs;
  if (!check_model(m, dir, error)) return false;
  *out = std::move(m);
  if (encoding) *encoding = enc;
  return true;
}

Files format_model(const Model &model, Encoding encoding) {
  const std::vector<Pose> poses = image_poses(model);
  return encoding == Encoding::Binary ? format_binary(model, poses) : format_text(model, poses);
}
bool model_writable(const std::string &dir, Encoding encoding, std::string *error) {
  // A directory made here goes with `probe`: the write makes it.
  OutputSet probe;
  if (!probe.make_directory(dir, error)) return false;
  std::string why;
  for (const ModelFile &file : kModelFiles) {
    const std::string path = slashed(dir) + file.name + extension(encoding);
    if (!probe_writable(path, &why)) return fail(error, path + ": " + why);
  }
  return true;
}

bool write_model(const std::string &dir, const Model &model, Encoding encoding, std::string *error,
                 OutputSet *outputs) {
  OutputSet own;
  OutputSet *set = outputs ? outputs : &own;
  if (!set->make_directory(dir, error)) return false;
  const Files files = format_model(model, encoding);
  for (const ModelFile &file : kModelFiles)
    if ((model.has_rigs || !file.rig_file) &&
        !write_whole_file(slashed(dir) + file.name + extension(encoding), files.*file.content, error, set))
      return false;
  // The other encoding's model goes, or a reader could take it for this one; its cameras file
  // first, without which no reader takes the others for a model.
  const bool text = encoding == Encoding::Text;
  const Encoding other = text ? Encoding::Binary : Encoding::Text;
  const char *why = text ? "COLMAP reads a folder's binary model first, and would have read it, not the text "
                           "model written"
                         : "a folder holds one model, and a reader that takes the text one would have read "
                           "stale values (COLMAP reads the binary one first)";
  for (auto file = std::rbegin(kModelFiles); file != std::rend(kModelFiles); ++file)
    set->remove_on_commit(slashed(dir) + file->name + extension(other),
                          text ? "the binary model" : "the text model", why);
  // So do rigs and frames of another model beside one without them: COLMAP 4 would take the
  // images' poses from those frames.
  if (!model.has_rigs)
    for (const ModelFile &file : kModelFiles)
      if (file.rig_file)
        set->remove_on_commit(slashed(dir) + file.name + extension(encoding),
                              "the rigs and frames of another model",
                              "the model written has none, and COLMAP 4 would compose its images' poses from "
                              "them");
  return outputs || own.commit(error);
}

}  // namespace sbaformats::colmap
