// SPDX-License-Identifier: BSD-3-Clause
#include "formats/colmap_sba.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <utility>

namespace sbaformats::colmap {

namespace cc = sbacameras::colmap_camera;

namespace {

std::size_t at(int i) { return static_cast<std::size_t>(i); }

bool fail(std::string *error, const std::string &msg) {
  if (error) *error = msg;
  return false;
}

}  // namespace

std::string parse_refine_intrinsics(const std::string &text, RefineIntrinsics *out) {
  RefineIntrinsics r{false, false, false};
  if (text == "all") {
    r = {true, true, true};
  } else if (text != "none") {
    std::size_t pos = 0;
    while (pos <= text.size()) {
      std::size_t end = text.find(',', pos);
      if (end == std::string::npos) end = text.size();
      const std::string item = text.substr(pos, end - pos);
      if (item == "focal") r.focal = true;
      else if (item == "principal") r.principal = true;
      else if (item == "distortion") r.distortion = true;
      else return "expected none, all or a comma-separated list of focal, principal, distortion, got '" + item + "'";
      pos = end + 1;
    }
  }
  *out = r;
  return {};
}

namespace {

// An item as a message quotes it: as given, but a control character as \xHH.
std::string quoted(const std::string &item) {
  std::string out = "'";
  for (const char c : item) {
    const unsigned char u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u != 0x7f) {
      out += c;
      continue;
    }
    char hex[5];
    std::snprintf(hex, sizeof hex, "\\x%02x", u);
    out += hex;
  }
  return out + "'";
}

// Whether item is written as an IMAGE_ID is (plain decimal digits, no leading zero), with its
// value in *id when an IMAGE_ID (32 bits) can have it.
bool plain_decimal(const std::string &item, std::uint32_t *id, bool *fits) {
  if (item.empty() || (item.size() > 1 && item[0] == '0')) return false;
  std::uint64_t v = 0;
  for (const char c : item) {
    if (c < '0' || c > '9') return false;
    if (v <= 0xffffffffu) v = 10 * v + static_cast<std::uint64_t>(c - '0');  // past 32 bits, stays past
  }
  *fits = v <= 0xffffffffu;
  *id = static_cast<std::uint32_t>(v);
  return true;
}

// Model::images by IMAGE_ID and by NAME (names may repeat), for the items of image lists.
class ImageLookup {
 public:
  explicit ImageLookup(const Model &model) {
    for (std::size_t j = 0; j < model.images.size(); ++j) {
      by_id_.emplace(model.images[j].id, j);
      by_name_.emplace(model.images[j].name, j);
    }
  }

  // Sets the flags of the images that item names, an item of digits an IMAGE_ID first when
  // ids. Returns why it names none, empty when it names one.
  std::string hold(const std::string &item, bool ids, std::vector<char> *held) const {
    std::uint32_t id = 0;
    bool fits = false;
    const bool digits = ids && plain_decimal(item, &id, &fits);
    if (digits && fits) {
      const auto it = by_id_.find(id);
      if (it != by_id_.end()) {
        (*held)[it->second] = 1;
        return {};
      }
    }
    const auto [first, last] = by_name_.equal_range(item);
    for (auto it = first; it != last; ++it) (*held)[it->second] = 1;
    if (first != last) return {};
    return std::string("no image has the ") + (digits ? "IMAGE_ID or NAME " : "NAME ") + quoted(item);
  }

 private:
  std::unordered_map<std::uint32_t, std::size_t> by_id_;
  std::unordered_multimap<std::string, std::size_t> by_name_;
};

}  // namespace

std::string split_image_list(const std::string &list, std::vector<std::string> *items) {
  std::vector<std::string> out;
  for (std::size_t pos = 0;;) {
    const std::size_t end = std::min(list.find(',', pos), list.size());
    if (end == pos)
      return "item " + std::to_string(out.size() + 1) +
             " is empty (two commas in a row, or a comma at an end)";
    out.push_back(list.substr(pos, end - pos));
    if (end == list.size()) break;
    pos = end + 1;
  }
  *items = std::move(out);
  return {};
}

std::string parse_image_list(const Model &model, const std::string &list, std::vector<char> *held) {
  std::vector<char> h = *held;
  h.resize(model.images.size(), 0);
  if (list == "all") {
    std::fill(h.begin(), h.end(), 1);
  } else {
    std::vector<std::string> items;
    if (std::string why = split_image_list(list, &items); !why.empty()) return why;
    const ImageLookup images(model);
    for (const std::string &item : items)
      if (std::string why = images.hold(item, true, &h); !why.empty()) return why;
  }
  *held = std::move(h);
  return {};
}

std::string parse_image_names(const Model &model, const std::string &text, const std::string &name,
                              std::vector<char> *held) {
  std::vector<char> h = *held;
  h.resize(model.images.size(), 0);
  const ImageLookup images(model);
  std::size_t pos = 0;
  for (int line = 1; pos < text.size(); ++line) {
    const std::size_t eol = std::min(text.find('\n', pos), text.size());
    // A '\r' is taken off only as part of a "\r\n" line break.
    const std::size_t end = eol < text.size() && eol > pos && text[eol - 1] == '\r' ? eol - 1 : eol;
    const std::string item = text.substr(pos, end - pos);
    pos = eol + 1;
    if (item.empty()) continue;
    if (std::string why = images.hold(item, false, &h); !why.empty())
      return name + ":" + std::to_string(line) + ": " + why;
  }
  *held = std::move(h);
  return {};
}

namespace {

// item as an identifier of at most max, written as an IMAGE_ID of an image list is (plain
// decimal digits without a leading zero): false when it is not one.
bool decimal_id(const std::string &item, std::uint64_t max, std::uint64_t *id) {
  if (item.empty() || (item.size() > 1 && item[0] == '0')) return false;
  std::uint64_t v = 0;
  for (const char c : item) {
    if (c < '0' || c > '9') return false;
    const std::uint64_t d = static_cast<std::uint64_t>(c - '0');
    if (v > (max - d) / 10) return false;
    v = 10 * v + d;
  }
  *id = v;
  return true;
}

std::string not_an_id(const std::string &item, const char *kind) {
  return quoted(item) + " is not a " + kind + " (plain decimal digits without a leading zero)";
}

// The identifiers of the elements of a model's list (Model::cameras, Model::points) and what
// messages call them, for the lists of identifiers.
struct IdIndex {
  const char *kind, *noun;  // "CAMERA_ID", "camera"
  std::uint64_t max;
  std::unordered_map<std::uint64_t, std::size_t> index;

  // Flags the element of item; why not, empty when it is flagged.
  std::string hold(const std::string &item, std::vector<char> *held) const {
    std::uint64_t id = 0;
    if (!decimal_id(item, max, &id)) return not_an_id(item, kind);
    const auto it = index.find(id);
    if (it == index.end()) return std::string("no ") + noun + " has the " + kind + " " + quoted(item);
    (*held)[it->second] = 1;
    return {};
  }
};

IdIndex camera_ids(const Model &model) {
  IdIndex ids{"CAMERA_ID", "camera", 0xffffffffu, {}};
  for (std::size_t c = 0; c < model.cameras.size(); ++c) ids.index.emplace(model.cameras[c].id, c);
  return ids;
}

IdIndex point_ids(const Model &model) {
  IdIndex ids{"POINT3D_ID", "point", UINT64_MAX, {}};
  for (std::size_t i = 0; i < model.points.size(); ++i) ids.index.emplace(model.points[i].id, i);
  return ids;
}

// parse_camera_list and parse_point_list over ids, of `size` elements.
std::string parse_id_list(const IdIndex &ids, std::size_t size, const std::string &list, std::vector<char> *held) {
  std::vector<char> h = *held;
  h.resize(size, 0);
  if (list == "all") {
    std::fill(h.begin(), h.end(), 1);
  } else {
    std::vector<std::string> items;
    if (std::string why = split_image_list(list, &items); !why.empty()) return why;
    for (const std::string &item : items)
      if (std::string why = ids.hold(item, &h); !why.empty()) return why;
  }
  *held = std::move(h);
  return {};
}

}  // namespace

std::string check_id_list(const std::string &list, const char *kind, std::uint64_t max) {
  if (list == "all") return {};
  std::vector<std::string> items;
  if (std::string why = split_image_list(list, &items); !why.empty()) return why;
  for (std::size_t k = 0; k < items.size(); ++k) {
    std::uint64_t id = 0;
    if (!decimal_id(items[k], max, &id)) return "item " + std::to_string(k + 1) + ": " + not_an_id(items[k], kind);
  }
  return {};
}

std::string parse_camera_list(const Model &model, const std::string &list, std::vector<char> *held) {
  return parse_id_list(camera_ids(model), model.cameras.size(), list, held);
}

std::string parse_point_list(const Model &model, const std::string &list, std::vector<char> *held) {
  return parse_id_list(point_ids(model), model.points.size(), list, held);
}

std::string parse_point_ids(const Model &model, const std::string &text, const std::string &name,
                            std::vector<char> *held) {
  std::vector<char> h = *held;
  h.resize(model.points.size(), 0);
  const IdIndex ids = point_ids(model);
  std::size_t pos = 0;
  for (int line = 1; pos < text.size(); ++line) {
    const std::size_t eol = std::min(text.find('\n', pos), text.size());
    // A '\r' is taken off only as part of a "\r\n" line break.
    const std::size_t end = eol < text.size() && eol > pos && text[eol - 1] == '\r' ? eol - 1 : eol;
    const std::string item = text.substr(pos, end - pos);
    pos = eol + 1;
    if (item.empty()) continue;
    if (std::string why = ids.hold(item, &h); !why.empty()) return name + ":" + std::to_string(line) + ": " + why;
  }
  *held = std::move(h);
  return {};
}

std::size_t frames_of_several_images(const Model &model) {
  return static_cast<std::size_t>(std::count_if(model.frames.begin(), model.frames.end(), [](const Frame &f) {
    return std::count_if(f.data.begin(), f.data.end(),
                         [](const DataId &d) { return d.sensor.type == SensorType::Camera; }) > 1;
  }));
}

namespace {

// Whether the model is refined through its rigs and frames (the rig camera model): when a
// frame holds several images, which then share its pose, or when the options hold what the
// frames' poses alone hold (COLMAP 4 then still refines the cameras' poses in their rigs). With
// every pose of a frame of one image refined, its image's pose is a free pose of its own
// however its camera sits in the rig: the model is refined as one without rigs, bit for bit.
bool refined_as_rigs(const Model &model, const RefinePoses &poses) {
  if (!model.has_rigs) return false;
  return !poses.rig_from_world || poses.constant_rig_from_world_rotation || frames_of_several_images(model) > 0;
}

// Whether COLMAP's options hold parameter k of a camera of model `model` (the padding beyond
// its parameters included).
bool intrinsic_held(const RefineIntrinsics &refine, int model, int k) {
  if (k >= cc::param_count(model)) return true;
  switch (cc::param_kind(model, k)) {
    case cc::ParamKind::Focal: return !refine.focal;
    case cc::ParamKind::Principal: return !refine.principal;
    case cc::ParamKind::Extra: return !refine.distortion;
    case cc::ParamKind::Size: break;  // no COLMAP option refines it
  }
  return true;
}

// Holds the rotation (first 3) and the translation (last 3) of the pose at fixed as asked.
void hold_pose(char *fixed, bool rotation, bool translation) {
  if (rotation) std::fill_n(fixed, 3, 1);
  if (translation) std::fill_n(fixed + 3, 3, 1);
}

// What holds a frame's pose, a camera's pose in its rig and its parameters in all their images
// of a rigged problem (flags by Model::frames and Model::cameras): an image below mcon (held
// whole) or, for the poses, a held image, whether it sees points or not: holding an image's
// pose holds both parts of it, so that it comes back as read.
struct RigHolds {
  std::vector<char> frame, sensor, camera;
};

// The sba cameras of a rigged problem (p->rig_images, p->places), their COLMAP cameras' indices
// in *camera; the largest parameter count among those cameras.
int rig_images(const Model &model, const std::vector<ImagePlace> &places,
               const std::unordered_map<std::uint32_t, int> &camera_index, std::vector<int> *camera,
               ColmapProblem *p) {
  int np = 0;
  for (const int i : p->images) {
    const Image &im = model.images[at(i)];
    const ImagePlace &pl = places[at(i)];
    camera->push_back(camera_index.at(im.camera_id));
    const Camera &c = model.cameras[at(camera->back())];
    cc::RigImage r;
    r.model = c.model;
    r.params = c.params;
    const Pose &f = model.frames[pl.frame].rig_from_world;
    r.q_frame = {f.q[0], f.q[1], f.q[2], f.q[3]};
    r.t_frame = f.t;
    if (pl.sensor > 0) {  // the reference sensor's pose in its rig is the identity
      const Pose &s = model.rigs[pl.rig].sensors[pl.sensor].sensor_from_rig;
      r.q_sensor = {s.q[0], s.q[1], s.q[2], s.q[3]};
      r.t_sensor = s.t;
    }
    np = std::max(np, cc::param_count(c.model));
    p->rig_images.push_back(std::move(r));
    p->places.push_back(pl);
  }
  return np;
}

// The flag of item k of flags, a vector of Constants (empty: none is set).
bool flagged(const std::vector<char> &flags, std::size_t k) { return !flags.empty() && flags[k]; }

// The holds of a rigged problem, and its counts (ColmapProblem: frames, sensors, shared cameras,
// held poses, images that see no point and move with a refined frame or rig).
RigHolds rig_holds(const Model &model, const RefinePoses &poses, const Constants &constants, int mcon,
                   const std::vector<ImagePlace> &places, const std::unordered_map<std::uint32_t, int> &camera_index,
                   ColmapProblem *p) {
  RigHolds h{std::vector<char>(model.frames.size(), poses.rig_from_world ? 0 : 1),
             std::vector<char>(model.cameras.size(), poses.sensor_from_rig ? 0 : 1),
             std::vector<char>(model.cameras.size(), 0)};
  for (std::size_t c = 0; c < model.cameras.size(); ++c) {
    if (flagged(constants.sensor_from_rig, c)) h.sensor[c] = 1;
    if (flagged(constants.intrinsics, c)) h.camera[c] = 1;
  }
  std::vector<char> frame_used(model.frames.size(), 0), sensor_used(model.cameras.size(), 0),
      seeing(model.images.size(), 0);
  std::vector<int> camera_used(model.cameras.size(), 0);  // images per camera: far more than a char holds
  for (std::size_t j = 0; j < p->images.size(); ++j) {
    const ImagePlace &pl = p->places[j];
    const std::size_t c = at(camera_index.at(model.images[at(p->images[j])].camera_id));
    if (static_cast<int>(j) < mcon) h.frame[pl.frame] = h.sensor[c] = h.camera[c] = 1;
    ++camera_used[c];
    frame_used[pl.frame] = 1;
    sensor_used[c] = pl.sensor > 0;
    seeing[at(p->images[j])] = 1;
  }
  for (std::size_t i = 0; i < model.images.size(); ++i) {
    if (!flagged(constants.poses, i)) continue;
    h.frame[places[i].frame] = h.sensor[at(camera_index.at(model.images[i].camera_id))] = 1;
    ++p->held_poses;
  }
  for (std::size_t f = 0; f < frame_used.size(); ++f) {
    p->frames += frame_used[f];
    p->held_frames += frame_used[f] && h.frame[f];
  }
  for (std::size_t c = 0; c < sensor_used.size(); ++c) {
    p->sensors += sensor_used[c];
    p->held_sensors += sensor_used[c] && h.sensor[c];
    p->shared_cameras += camera_used[c] > 1 && !h.camera[c];
    p->held_intrinsics += camera_used[c] > 0 && flagged(constants.intrinsics, c);
  }
  // An image that sees no point keeps its place in its frame and rig: it moves when the frame's
  // pose, or its camera's pose in the rig, is refined for the images that see points.
  for (std::size_t i = 0; i < model.images.size(); ++i) {
    if (seeing[i]) continue;
    const std::size_t f = places[i].frame, c = at(camera_index.at(model.images[i].camera_id));
    p->unseen_moved += (frame_used[f] && !h.frame[f]) || (sensor_used[c] && !h.sensor[c]);
  }
  return h;
}

// The rigged problem's cameras, held flags and groups (ColmapProblem), its cameras' images in
// p->images; camera_index maps a CAMERA_ID to its index in Model::cameras.
void rig_problem(const Model &model, const RefineIntrinsics &refine, const RefinePoses &poses,
                 const Constants &constants, int mcon, const std::unordered_map<std::uint32_t, int> &camera_index,
                 ColmapProblem *p) {
  const std::vector<ImagePlace> places = image_places(model);
  const int ms = static_cast<int>(p->images.size());
  p->rigged = true;
  std::vector<int> camera;  // each sba camera's index in Model::cameras
  const int cnp = p->cnp = cc::rig_camera_params(rig_images(model, places, camera_index, &camera, p));
  const RigHolds h = rig_holds(model, poses, constants, mcon, places, camera_index, p);
  p->cam_fixed.assign(at(ms) * at(cnp), 0);
  p->cam_param_group.assign(at(ms) * at(cnp), -1);
  for (int j = 0; j < ms; ++j) {
    const ImagePlace &pl = p->places[at(j)];
    const int c = camera[at(j)], model_id = model.cameras[at(c)].model;
    char *fixed = &p->cam_fixed[at(j) * at(cnp)];
    int *group = &p->cam_param_group[at(j) * at(cnp)];
    const bool reference = pl.sensor == 0;
    hold_pose(fixed, h.frame[pl.frame] || poses.constant_rig_from_world_rotation, h.frame[pl.frame]);
    hold_pose(fixed + 6, reference || h.sensor[at(c)], reference || h.sensor[at(c)]);
    for (int k = 0; k < cnp - cc::kRigPoseParams; ++k)
      fixed[cc::kRigPoseParams + k] = h.camera[at(c)] || intrinsic_held(refine, model_id, k) ? 1 : 0;
    if (j < mcon) continue;  // a camera below mcon shares nothing
    std::fill_n(group, 6, static_cast<int>(pl.frame));
    if (!reference) std::fill_n(group + 6, 6, c);
    std::fill(group + cc::kRigPoseParams, group + cnp, c);
  }
}

// The unrigged problem's cameras, held flags and groups (ColmapProblem), as rig_problem.
void image_problem(const Model &model, const RefineIntrinsics &refine, const RefinePoses &poses,
                   const Constants &constants, int mcon, const std::unordered_map<std::uint32_t, int> &camera_index,
                   ColmapProblem *p) {
  int np = 0;
  for (int j : p->images) {
    const Image &im = model.images[at(j)];
    const Camera &c = model.cameras[at(camera_index.at(im.camera_id))];
    cc::Camera cam;
    cam.model = c.model;
    cam.params = c.params;
    cam.q = {im.q[0], im.q[1], im.q[2], im.q[3]};
    for (int k = 0; k < 3; ++k) cam.t[at(k)] = im.t[at(k)];
    np = std::max(np, cc::param_count(c.model));
    p->cameras.push_back(std::move(cam));
  }
  const int ms = static_cast<int>(p->cameras.size());
  const int cnp = p->cnp = cc::camera_params(np);
  // Each COLMAP camera's sba cameras; one below mcon holds the camera's parameters in all, and so
  // do constant intrinsics.
  std::vector<std::vector<int>> users(model.cameras.size());
  for (int j = 0; j < ms; ++j) users[at(camera_index.at(model.images[at(p->images[at(j)])].camera_id))].push_back(j);
  p->cam_fixed.assign(at(ms) * at(cnp), 0);
  p->cam_group.assign(at(ms), -1);
  p->cam_shared.assign(at(cnp), 0);
  for (int k = cc::kPoseParams; k < cnp; ++k) p->cam_shared[at(k)] = 1;
  for (std::size_t c = 0; c < users.size(); ++c) {
    const std::vector<int> &u = users[c];
    if (u.empty()) continue;
    const bool held = u.front() < mcon || flagged(constants.intrinsics, c);  // u ascends
    for (int j : u) {
      char *fixed = &p->cam_fixed[at(j) * at(cnp)];
      for (int k = 0; k < cnp - cc::kPoseParams; ++k)
        fixed[cc::kPoseParams + k] = held || intrinsic_held(refine, model.cameras[c].model, k) ? 1 : 0;
      if (u.size() > 1 && !held) p->cam_group[at(j)] = u.front();
    }
    if (u.size() > 1 && !held) ++p->shared_cameras;
    p->held_intrinsics += flagged(constants.intrinsics, c);
  }
  std::vector<char> seeing(model.images.size(), 0);
  for (int j = 0; j < ms; ++j) {
    const bool held = !poses.rig_from_world || flagged(constants.poses, at(p->images[at(j)]));
    hold_pose(&p->cam_fixed[at(j) * at(cnp)], held || poses.constant_rig_from_world_rotation, held);
    p->held_poses += held;
    seeing[at(p->images[at(j)])] = 1;
  }
  // A held image that sees no point is held out of the problem, and counted as held too.
  for (std::size_t i = 0; i < seeing.size(); ++i) p->held_poses += !seeing[i] && flagged(constants.poses, i);
}

}  // namespace

namespace {

// The order of the problem's points (ColmapProblem::point_order) and how many lead it held
// (held_points): with constant points, the first ncon points and the constant ones, in the
// file's order, then the others; otherwise the file's order and ncon as given.
void order_points(const Model &model, const std::vector<char> &constant, int ncon, ColmapProblem *p) {
  p->held_points = ncon;
  if (constant.empty()) return;
  const std::size_t n = model.points.size();
  if (ncon >= static_cast<int>(n)) return;  // every point held, or a --ncon the solve refuses
  const auto held = [&](std::size_t i) { return static_cast<int>(i) < ncon || constant[i]; };
  for (const bool first : {true, false})
    for (std::size_t i = 0; i < n; ++i)
      if (held(i) == first) p->point_order.push_back(static_cast<int>(i));
  p->held_points = static_cast<int>(std::count_if(p->point_order.begin(), p->point_order.end(),
                                                  [&](int i) { return held(at(i)); }));
}

// The problem's points and their projections (ColmapProblem::points) in the order of
// order_points; camera_of: each image's sba camera, image_index: an IMAGE_ID's image.
void problem_points(const Model &model, const std::unordered_map<std::uint32_t, int> &image_index,
                    const std::vector<int> &camera_of, ColmapProblem *p) {
  const int n = static_cast<int>(model.points.size());
  eucsba::PointSet &s = p->points;
  s.ncameras = static_cast<int>(p->images.size());
  s.xyz.reserve(at(n) * 3);
  std::vector<std::pair<int, const Point2D *>> track;
  for (int k = 0; k < n; ++k) {
    const Point3D &pt = model.points[p->point_order.empty() ? at(k) : at(p->point_order[at(k)])];
    s.xyz.insert(s.xyz.end(), pt.xyz.begin(), pt.xyz.end());
    track.clear();
    for (const TrackElement &e : pt.track) {
      const int j = image_index.at(e.image_id);
      track.push_back({camera_of[at(j)], &model.images[at(j)].points[e.point2d_idx]});
    }
    // sba's layout: a point's projections with the cameras ascending.
    std::sort(track.begin(), track.end(),
              [](const std::pair<int, const Point2D *> &a, const std::pair<int, const Point2D *> &b) {
                return a.first < b.first;
              });
    for (const auto &t : track) {
      s.pairs.add(k, t.first);
      s.x.push_back(t.second->x);
      s.x.push_back(t.second->y);
    }
  }
}

}  // namespace

bool to_sba(const Model &model, const RefineIntrinsics &refine, const RefinePoses &poses,
            const Constants &constants, int mcon, int ncon, const std::string &name, ColmapProblem *out,
            std::string *error) {
  const std::string where = name + ": ";
  std::unordered_map<std::uint32_t, int> camera_index, image_index;
  for (std::size_t c = 0; c < model.cameras.size(); ++c) camera_index.emplace(model.cameras[c].id, static_cast<int>(c));
  const int m = static_cast<int>(model.images.size());
  const int n = static_cast<int>(model.points.size());
  if (m == 0 || n == 0) return fail(error, where + "the model has no images or no points");
  for (int j = 0; j < m; ++j) image_index.emplace(model.images[at(j)].id, j);
  // An image is a camera of the problem when it sees a point (every point is seen: check_model).
  std::vector<int> camera_of(at(m), -1);
  for (const Point3D &pt : model.points)
    for (const TrackElement &e : pt.track) camera_of[at(image_index.at(e.image_id))] = 0;
  ColmapProblem p;
  for (int j = 0; j < m; ++j)
    if (camera_of[at(j)] >= 0) {
      camera_of[at(j)] = static_cast<int>(p.images.size());
      p.images.push_back(j);
    }
  if (refined_as_rigs(model, poses))
    rig_problem(model, refine, poses, constants, mcon, camera_index, &p);
  else
    image_problem(model, refine, poses, constants, mcon, camera_index, &p);
  order_points(model, constants.points, ncon, &p);
  problem_points(model, image_index, camera_of, &p);
  *out = std::move(p);
  return true;
}

bool to_sba(const Model &model, const RefineIntrinsics &refine, const RefinePoses &poses,
            const std::vector<char> &held_pose, int mcon, const std::string &name, ColmapProblem *out,
            std::string *error) {
  Constants constants;
  constants.poses = held_pose;
  return to_sba(model, refine, poses, constants, mcon, 0, name, out, error);
}

std::string nonfinite_error(const Model &model, const ColmapProblem &problem, const std::string &name,
                            const std::function<void(int j, int i, double x[2])> &project) {
  const eucsba::PointSet &s = problem.points;
  for (std::size_t k = 0; k < s.pairs.size(); ++k) {
    const int i = s.pairs.point[k], j = s.pairs.camera[k];
    double x[2];
    project(j, i, x);
    const double dx = x[0] - s.x[2 * k], dy = x[1] - s.x[2 * k + 1];
    if (std::isfinite(dx * dx + dy * dy)) continue;
    const Image &im = model.images[at(problem.images[at(j)])];
    const auto camera = std::find_if(model.cameras.begin(), model.cameras.end(),
                                     [&](const Camera &c) { return c.id == im.camera_id; });
    char pixels[64];
    std::snprintf(pixels, sizeof pixels, "(%g, %g)", x[0], x[1]);
    const std::string image_name = quoted(im.name);  // its control characters as \xHH, in quotes
    return name + ": image " + std::to_string(im.id) + " (" + image_name.substr(1, image_name.size() - 2) +
           "), camera " + std::to_string(im.camera_id) + " (" + camera_model_name(camera->model) + "): point " +
           std::to_string(model.points[problem.point_order.empty() ? at(i) : at(problem.point_order[at(i)])].id) +
           " projects to " + pixels +
           " px, where its squared reprojection error is not finite";
  }
  return {};
}

namespace {

// Writes a refined pose over (*q, *t): the rotation unless its 3 parameters are all held, the
// translation unless its 3 are, so that a held part keeps the bits it was read with (the
// parametrization's round trip would move them). Whether anything was written.
bool write_pose(const char *fixed, const sbacameras::euclidean::Quaternion &q, const std::array<double, 3> &t,
                std::array<double, 4> *q_out, std::array<double, 3> *t_out) {
  const auto held = [](const char *f) { return f[0] && f[1] && f[2]; };
  if (!held(fixed)) *q_out = {q.w, q.x, q.y, q.z};
  if (!held(fixed + 3)) *t_out = t;
  return !held(fixed) || !held(fixed + 3);
}

// Each refined point (the problem's from ncon on, in the model's place of each) from p, its
// ERROR the mean distance in pixels between its observations and project(j, a_j, b_i, x).
template <typename Project>
void write_points(const ColmapProblem &problem, const double *p, int cnp, int ncon, Project project, Model *model) {
  const int m = static_cast<int>(problem.images.size());
  const int n = static_cast<int>(model->points.size());
  std::unordered_map<std::uint32_t, int> camera_of;  // an image's sba camera
  for (int j = 0; j < m; ++j) camera_of.emplace(model->images[at(problem.images[at(j)])].id, j);
  const double *points = p + at(m) * at(cnp);
  for (int k = ncon; k < n; ++k) {
    Point3D &pt = model->points[problem.point_order.empty() ? at(k) : at(problem.point_order[at(k)])];
    const double *b = points + 3 * at(k);
    for (int c = 0; c < 3; ++c) pt.xyz[at(c)] = b[c];
    double sum = 0;
    for (const TrackElement &e : pt.track) {
      const int j = camera_of.at(e.image_id);
      const Point2D &obs = model->images[at(problem.images[at(j)])].points[e.point2d_idx];
      double x[2];
      project(j, p + at(j) * at(cnp), b, x);
      sum += std::hypot(x[0] - obs.x, x[1] - obs.y);
    }
    pt.error = sum / static_cast<double>(pt.track.size());
  }
}

// The parameters of COLMAP camera `cam` that are not held (fixed: its intrinsics' flags) from
// params.
void write_params(const char *fixed, const std::vector<double> &params, Camera *cam) {
  for (std::size_t k = 0; k < cam->params.size(); ++k)
    if (!fixed[k]) cam->params[k] = params[k];
}

}  // namespace

void from_sba(const cc::CameraModel &sba_model, const ColmapProblem &problem, const double *p, int mcon, int ncon,
              Model *model) {
  const int m = static_cast<int>(problem.images.size());
  const int cnp = sba_model.cnp();
  std::unordered_map<std::uint32_t, Camera *> cameras;
  for (Camera &c : model->cameras) cameras.emplace(c.id, &c);
  std::vector<char> posed(model->images.size(), 0);  // the images whose pose is written
  for (int j = mcon; j < m; ++j) {
    Image &im = model->images[at(problem.images[at(j)])];
    const char *fixed = &problem.cam_fixed[at(j) * at(cnp)];
    const cc::Camera c = sba_model.camera(j, p + at(j) * at(cnp));
    posed[at(problem.images[at(j)])] = write_pose(fixed, c.q, c.t, &im.q, &im.t);
    const int group = problem.cam_group[at(j)];
    if (group >= 0 && group != j) continue;  // the group's first camera writes it
    write_params(fixed + cc::kPoseParams, c.params, cameras.at(im.camera_id));
  }
  write_points(problem, p, cnp, ncon,
               [&](int j, const double *a, const double *b, double *x) { sba_model.project(j, a, b, x); }, model);
  // COLMAP 4 reads the poses from the frames (each of one image: to_sba).
  frames_from_poses(model, posed);
}

void from_sba(const cc::RigCameraModel &sba_model, const ColmapProblem &problem, const double *p, int mcon,
              int ncon, Model *model) {
  const int m = static_cast<int>(problem.images.size());
  const int cnp = sba_model.cnp();
  std::unordered_map<std::uint32_t, Camera *> cameras;
  for (Camera &c : model->cameras) cameras.emplace(c.id, &c);
  // Each frame, sensor and COLMAP camera is written once, from its first sba camera: all of
  // them hold the same values.
  std::vector<char> frame_done(model->frames.size(), 0);
  std::unordered_map<std::uint32_t, char> camera_done;  // flags, set once
  for (int j = mcon; j < m; ++j) {
    const ImagePlace &pl = problem.places[at(j)];
    const char *fixed = &problem.cam_fixed[at(j) * at(cnp)];
    const cc::RigImage r = sba_model.image(j, p + at(j) * at(cnp));
    if (!frame_done[pl.frame]) {
      Pose &f = model->frames[pl.frame].rig_from_world;
      write_pose(fixed, r.q_frame, r.t_frame, &f.q, &f.t);
      frame_done[pl.frame] = 1;
    }
    const std::uint32_t camera_id = model->images[at(problem.images[at(j)])].camera_id;
    char &done = camera_done[camera_id];
    if (done) continue;
    done = 1;
    if (pl.sensor > 0) {
      Pose &s = model->rigs[pl.rig].sensors[pl.sensor].sensor_from_rig;
      write_pose(fixed + 6, r.q_sensor, r.t_sensor, &s.q, &s.t);
    }
    write_params(fixed + cc::kRigPoseParams, r.params, cameras.at(camera_id));
  }
  write_points(problem, p, cnp, ncon,
               [&](int j, const double *a, const double *b, double *x) { sba_model.project(j, a, b, x); }, model);
  poses_from_frames(model);
}

bool to_euclidean(const cc::Camera &c, sbacameras::euclidean::Camera *out) {
  sbacameras::euclidean::Camera e;
  const std::vector<double> &p = c.params;
  int nd = 0;  // Bouguet's kc = (k1 k2 p1 p2 k3) is OpenCV's
  switch (c.model) {
    case kSimplePinhole: case kSimpleRadial: case kRadial:
      e.k.fu = p[0];
      e.k.u0 = p[1];
      e.k.v0 = p[2];
      nd = c.model == kSimplePinhole ? 0 : c.model == kSimpleRadial ? 1 : 2;
      for (int k = 0; k < nd; ++k) e.kc[at(k)] = p[at(3 + k)];
      break;
    case kPinhole: case kOpenCV:
      e.k.fu = p[0];
      e.k.ar = p[1] / p[0];
      e.k.u0 = p[2];
      e.k.v0 = p[3];
      nd = c.model == kPinhole ? 0 : 4;
      for (int k = 0; k < nd; ++k) e.kc[at(k)] = p[at(4 + k)];
      break;
    default: return false;
  }
  e.q = c.q;
  e.t = c.t;
  *out = e;
  return true;
}

}  // namespace sbaformats::colmap

namespace sbaformats::colmap {

bool from_problem(sbacameras::euclidean::CameraKind kind, const std::vector<sbacameras::euclidean::Camera> &cameras, const eucsba::PointSet &points,
                  int width, int height, Model *out, std::string *error) {
  const int m = static_cast<int>(cameras.size()), n = points.npoints();
  if (points.ncameras != m || points.vmask.size() != static_cast<std::size_t>(n) * static_cast<std::size_t>(m))
    return fail(error, "a COLMAP model needs the points' dense visibility mask");
  Model model;
  const bool shared = kind == sbacameras::euclidean::CameraKind::FixedIntrinsics;
  const bool distortion = kind == sbacameras::euclidean::CameraKind::VaryingIntrinsicsDistortion;
  for (int j = 0; j < m; ++j) {
    const sbacameras::euclidean::Camera &c = cameras[static_cast<std::size_t>(j)];
    if (c.k.s != 0) return fail(error, "camera " + std::to_string(j) + " has a skew, which COLMAP cannot hold");
    if (c.kc[4] != 0) return fail(error, "camera " + std::to_string(j) + " has kc4 (k3), which OPENCV cannot hold");
    if (!shared || j == 0) {
      Camera cam;
      cam.id = shared ? 1 : 100 + static_cast<std::uint32_t>(j);
      cam.model = distortion ? kOpenCV : kPinhole;
      cam.width = static_cast<std::uint64_t>(width);
      cam.height = static_cast<std::uint64_t>(height);
      cam.params = {c.k.fu, c.k.fu * c.k.ar, c.k.u0, c.k.v0};
      if (distortion) cam.params.insert(cam.params.end(), c.kc.begin(), c.kc.begin() + 4);
      model.cameras.push_back(cam);
    }
    Image im;
    im.id = 10 + 3 * static_cast<std::uint32_t>(j);
    im.q = {c.q.w, c.q.x, c.q.y, c.q.z};
    for (int k = 0; k < 3; ++k) im.t[k] = c.t[k];
    im.camera_id = model.cameras.back().id;
    char name[32];
    std::snprintf(name, sizeof name, "img_%04d.png", j);
    im.name = name;
    im.points.push_back({0.5, 0.5, kNoPoint});
    model.images.push_back(std::move(im));
  }
  model.points.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    Point3D &pt = model.points[static_cast<std::size_t>(i)];
    pt.id = 1000 + 7 * static_cast<std::uint64_t>(i);
    for (int c = 0; c < 3; ++c) pt.xyz[c] = points.xyz[3 * static_cast<std::size_t>(i) + c];
    const std::array<int, 3> rgb = eucsba::generated_color(i);
    for (int c = 0; c < 3; ++c) pt.rgb[c] = static_cast<std::uint8_t>(rgb[c]);
    pt.error = 1;
  }
  eucsba::for_each_projection(points, [&](int i, int j, const double *x) {
    Point3D &pt = model.points[static_cast<std::size_t>(i)];
    Image &im = model.images[static_cast<std::size_t>(j)];
    pt.track.push_back({im.id, static_cast<std::uint32_t>(im.points.size())});
    im.points.push_back({x[0], x[1], pt.id});
  });
  *out = std::move(model);
  return true;
}

}  // namespace sbaformats::colmap
