// SPDX-License-Identifier: BSD-3-Clause
#include "formats/colmap_problem.h"

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <unordered_map>
#include <utility>

namespace sbaformats::colmap {

namespace cc = sbacameras::colmap_camera;

bool colmap_stop_rule(double function_tolerance, double gradient_tolerance, bool strategy_given, double *eps1,
                      double *eps4) {
  if (function_tolerance < 0 && !strategy_given && *eps4 == 0.0) function_tolerance = 0.0;
  const bool applies = function_tolerance >= 0;
  if (applies) *eps4 = std::max(function_tolerance, 4 * std::numeric_limits<double>::epsilon());
  if (gradient_tolerance >= 0)
    *eps1 = gradient_tolerance;
  else if (applies && *eps1 == SBA_STOP_THRESH)
    *eps1 = kColmapGradientTolerance;
  return applies;
}

namespace {

std::size_t at(int i) { return static_cast<std::size_t>(i); }

// The problem as the builder lays it out, before the camera model is made of it: the sba
// cameras as images of their own (cameras) or of rigs (rig_images, places), their holds and
// groups, the points.
struct Draft {
  std::vector<cc::Camera> cameras;
  std::vector<std::vector<int>> kept;  // each camera's model parameters that a_j carries (CameraModel)
  std::vector<int> images;
  eucsba::PointSet points;
  int cnp = 0;
  std::vector<char> cam_fixed;
  std::vector<int> cam_param_group;
  Problem::Counts counts;
  bool rigged = false;
  std::vector<cc::RigImage> rig_images;
  std::vector<ImagePlace> places;
  std::vector<ImagePlace> image_places;  // each image's, in a model with rigs: built once, by draft_of
  std::vector<int> point_order;
  int held_points = 0;
};

// Whether the model is refined through its rigs and frames (the rig camera model): when a
// frame holds several images, which then share its pose, or when the options hold what the
// frames' poses alone hold (COLMAP 4 then still refines the cameras' poses in their rigs). With
// every pose of a frame of one image refined, its image's pose is a free pose of its own
// however its camera sits in the rig: the model is refined as one without rigs, bit for bit.
// A frame of one image that is held while its camera's pose in the rig is refined for other
// frames (a constant rig_from_world, an image outside the config) moves with that pose: frames_held
// says there may be one, places where the images are (a camera that is a rig's reference has no
// such pose).
bool refined_as_rigs(const Model &model, const RefinePoses &poses, bool frames_held,
                     const std::vector<ImagePlace> &places) {
  if (!model.has_rigs) return false;
  if (!poses.rig_from_world || poses.constant_rig_from_world_rotation || frames_of_several_images(model) > 0)
    return true;
  return frames_held && std::any_of(places.begin(), places.end(), [](const ImagePlace &pl) { return pl.sensor > 0; });
}

// Whether COLMAP's options hold parameter k of a camera of model `model`.
bool intrinsic_held(const RefineIntrinsics &refine, int model, int k) {
  switch (cc::param_kind(model, k)) {
    case cc::ParamKind::Focal: return !refine.focal;
    case cc::ParamKind::Principal: return !refine.principal;
    case cc::ParamKind::Extra: return !refine.distortion;
    case cc::ParamKind::Size: break;  // no COLMAP option refines it
  }
  return true;
}

// The parameters of a camera of model `model` that COLMAP's options refine, none when the
// camera is held: what its sba cameras' vectors carry (CameraModel's kept).
std::vector<int> refined_params(const RefineIntrinsics &refine, int model, bool held) {
  std::vector<int> kept;
  for (int k = 0; !held && k < cc::param_count(model); ++k)
    if (!intrinsic_held(refine, model, k)) kept.push_back(k);
  return kept;
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
// in *camera.
void rig_images(const Model &model, const std::vector<ImagePlace> &places,
               const std::unordered_map<std::uint32_t, int> &camera_index, std::vector<int> *camera,
               Draft *p) {
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
    p->rig_images.push_back(std::move(r));
    p->places.push_back(pl);
  }
}

// The flag of item k of flags, a vector of Constants (empty: none is set).
bool flagged(const std::vector<char> &flags, std::size_t k) { return !flags.empty() && flags[k]; }

// The holds of a rigged problem, and its counts (Draft: frames, sensors, shared cameras,
// held poses, images that see no point and move with a refined frame or rig).
RigHolds rig_holds(const Model &model, const RefinePoses &poses, const Constants &constants,
                   const std::vector<char> &config, int mcon, const std::vector<ImagePlace> &places,
                   const std::unordered_map<std::uint32_t, int> &camera_index, Draft *p) {
  RigHolds h{std::vector<char>(model.frames.size(), poses.rig_from_world ? 0 : 1),
             std::vector<char>(model.cameras.size(), poses.sensor_from_rig ? 0 : 1),
             std::vector<char>(model.cameras.size(), 0)};
  for (std::size_t c = 0; c < model.cameras.size(); ++c) {
    if (flagged(constants.sensor_from_rig, c)) h.sensor[c] = 1;
    if (flagged(constants.intrinsics, c)) h.camera[c] = 1;
  }
  for (std::size_t f = 0; f < model.frames.size(); ++f)
    if (flagged(constants.frames, f)) h.frame[f] = 1;
  // Outside the config's images, what no config image refines is held.
  if (!config.empty()) {
    std::vector<char> frame_config(model.frames.size(), 0), camera_config(model.cameras.size(), 0);
    for (const int i : p->images) {
      if (!config[at(i)]) continue;
      frame_config[places[at(i)].frame] = 1;
      camera_config[at(camera_index.at(model.images[at(i)].camera_id))] = 1;
    }
    for (std::size_t f = 0; f < frame_config.size(); ++f) h.frame[f] |= !frame_config[f];
    for (std::size_t c = 0; c < camera_config.size(); ++c)
      if (!camera_config[c]) h.sensor[c] = h.camera[c] = 1;
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
    ++p->counts.held_poses;
  }
  for (std::size_t f = 0; f < frame_used.size(); ++f) {
    p->counts.frames += frame_used[f];
    p->counts.held_frames += frame_used[f] && h.frame[f];
  }
  for (std::size_t c = 0; c < sensor_used.size(); ++c) {
    p->counts.sensors += sensor_used[c];
    p->counts.held_sensors += sensor_used[c] && h.sensor[c];
    p->counts.shared_cameras += camera_used[c] > 1 && !h.camera[c];
    p->counts.held_intrinsics += camera_used[c] > 0 && flagged(constants.intrinsics, c);
  }
  // An image that sees no point keeps its place in its frame and rig: it moves when the frame's
  // pose, or its camera's pose in the rig, is refined for the images that see points.
  for (std::size_t i = 0; i < model.images.size(); ++i) {
    if (seeing[i]) continue;
    const std::size_t f = places[i].frame, c = at(camera_index.at(model.images[i].camera_id));
    p->counts.unseen_moved += (frame_used[f] && !h.frame[f]) || (sensor_used[c] && !h.sensor[c]);
  }
  return h;
}

// The rigged problem's cameras, held flags and groups (Draft), its cameras' images in
// p->images; camera_index maps a CAMERA_ID to its index in Model::cameras.
void rig_problem(const Model &model, const RefineIntrinsics &refine, const RefinePoses &poses,
                 const Constants &constants, const std::vector<char> &config, int mcon,
                 const std::unordered_map<std::uint32_t, int> &camera_index, Draft *p) {
  const std::vector<ImagePlace> &places = p->image_places;
  const int ms = static_cast<int>(p->images.size());
  p->rigged = true;
  std::vector<int> camera;  // each sba camera's index in Model::cameras
  rig_images(model, places, camera_index, &camera, p);
  const RigHolds h = rig_holds(model, poses, constants, config, mcon, places, camera_index, p);
  // The parameters held take no column (RigCameraModel's kept), as in image_problem.
  for (int j = 0; j < ms; ++j) {
    const int c = camera[at(j)];
    p->kept.push_back(refined_params(refine, model.cameras[at(c)].model, h.camera[at(c)]));
  }
  const int cnp = p->cnp = cc::rig_camera_params(cc::largest_kept(p->kept));
  p->cam_fixed.assign(at(ms) * at(cnp), 0);
  p->cam_param_group.assign(at(ms) * at(cnp), -1);
  for (int j = 0; j < ms; ++j) {
    const ImagePlace &pl = p->places[at(j)];
    const int c = camera[at(j)];
    char *fixed = &p->cam_fixed[at(j) * at(cnp)];
    int *group = &p->cam_param_group[at(j) * at(cnp)];
    const bool reference = pl.sensor == 0;
    hold_pose(fixed, h.frame[pl.frame] || poses.constant_rig_from_world_rotation, h.frame[pl.frame]);
    hold_pose(fixed + 6, reference || h.sensor[at(c)], reference || h.sensor[at(c)]);
    std::fill(fixed + cc::kRigPoseParams + p->kept[at(j)].size(), fixed + cnp, 1);  // the padding
    if (j < mcon) continue;  // a camera below mcon shares nothing
    std::fill_n(group, 6, static_cast<int>(pl.frame));
    if (!reference) std::fill_n(group + 6, 6, c);
    std::fill(group + cc::kRigPoseParams, group + cnp, c);
  }
}

// The unrigged problem's cameras, held flags and groups (Draft), as rig_problem.
void image_problem(const Model &model, const RefineIntrinsics &refine, const RefinePoses &poses,
                   const Constants &constants, const std::vector<char> &config, int mcon,
                   const std::unordered_map<std::uint32_t, int> &camera_index, Draft *p) {
  // A frame of one image: its image's pose.
  const std::vector<Pose> image_pose = image_poses(model, p->image_places);
  for (int j : p->images) {
    const Image &im = model.images[at(j)];
    const Pose &pose = image_pose[at(j)];
    const Camera &c = model.cameras[at(camera_index.at(im.camera_id))];
    cc::Camera cam;
    cam.model = c.model;
    cam.params = c.params;
    cam.q = {pose.q[0], pose.q[1], pose.q[2], pose.q[3]};
    cam.t = pose.t;
    p->cameras.push_back(std::move(cam));
  }
  const int ms = static_cast<int>(p->cameras.size());
  // Each COLMAP camera's sba cameras; one below mcon holds the camera's parameters in all, and so
  // do constant intrinsics. The parameters held take no column (CameraModel's kept): a_j
  // carries the camera's free parameters alone.
  std::vector<std::vector<int>> users(model.cameras.size());
  for (int j = 0; j < ms; ++j) users[at(camera_index.at(model.images[at(p->images[at(j)])].camera_id))].push_back(j);
  std::vector<char> camera_held(model.cameras.size(), 0);
  p->kept.assign(at(ms), {});
  for (std::size_t c = 0; c < users.size(); ++c) {
    const std::vector<int> &u = users[c];
    if (u.empty()) continue;
    // Outside the config's images, a camera no config image uses is held.
    const bool outside = !config.empty() && std::none_of(u.begin(), u.end(), [&](int j) {
      return config[at(p->images[at(j)])] != 0;
    });
    const bool held = u.front() < mcon || flagged(constants.intrinsics, c) || outside;  // u ascends
    camera_held[c] = held;
    const std::vector<int> kept = refined_params(refine, model.cameras[c].model, held);
    for (int j : u) p->kept[at(j)] = kept;
  }
  const int cnp = p->cnp = cc::camera_params(cc::largest_kept(p->kept));
  p->cam_fixed.assign(at(ms) * at(cnp), 0);
  p->cam_param_group.assign(at(ms) * at(cnp), -1);
  for (std::size_t c = 0; c < users.size(); ++c) {
    const std::vector<int> &u = users[c];
    if (u.empty()) continue;
    const bool held = camera_held[c];
    for (int j : u) {
      // Beyond the parameters kept, the padding.
      char *fixed = &p->cam_fixed[at(j) * at(cnp)];
      std::fill(fixed + cc::kPoseParams + p->kept[at(j)].size(), fixed + cnp, 1);
      // The camera's parameters, not the image's pose, in the group of its first sba camera.
      if (u.size() > 1 && !held)
        std::fill(&p->cam_param_group[at(j) * at(cnp) + cc::kPoseParams], &p->cam_param_group[at(j + 1) * at(cnp)],
                  u.front());
    }
    if (u.size() > 1 && !held) ++p->counts.shared_cameras;
    p->counts.held_intrinsics += flagged(constants.intrinsics, c);
  }
  std::vector<char> seeing(model.images.size(), 0);
  for (int j = 0; j < ms; ++j) {
    const std::size_t i = at(p->images[at(j)]);
    // A frame of this image alone (refined_as_rigs): holding it holds the image's pose.
    const bool held = !poses.rig_from_world || flagged(constants.poses, i) || (!config.empty() && !config[i]) ||
                      (model.has_rigs && flagged(constants.frames, p->image_places[i].frame));
    hold_pose(&p->cam_fixed[at(j) * at(cnp)], held || poses.constant_rig_from_world_rotation, held);
    p->counts.held_poses += held;
    seeing[at(p->images[at(j)])] = 1;
  }
  // A held image that sees no point is held out of the problem, and counted as held too.
  for (std::size_t i = 0; i < seeing.size(); ++i) p->counts.held_poses += !seeing[i] && flagged(constants.poses, i);
}



// The points and observations of the problem (Selection), by Model::points: whether a point is
// in it, held (before the gauge's), and which of its observations it takes: those in the
// config's images (Config), every one (Every), or those and the ones in images outside the
// config that have something refined (Moving).
struct Chosen {
  enum Reach : char { Config, Every, Moving };
  std::vector<char> in, held, reach;
  std::vector<char> config;  // by Model::images: a config image (empty: every image)
  std::vector<char> moving;  // by Model::images: outside the config, with something refined
  bool takes(std::size_t point, std::size_t image) const {
    return config.empty() || config[image] || reach[point] == Every || (reach[point] == Moving && moving[image]);
  }
};

// The selection of o over the model (image_index: an IMAGE_ID's image, places: the images' in a
// model with rigs), before the gauge.
Chosen choose(const Model &model, const Options &o, const std::unordered_map<std::uint32_t, int> &image_index,
              const std::unordered_map<std::uint32_t, int> &camera_index, const std::vector<ImagePlace> &places) {
  const Selection &sel = o.selection;
  const std::size_t n = model.points.size();
  Chosen ch;
  ch.in.assign(n, 1);
  ch.reach.assign(n, Chosen::Every);
  ch.held.assign(n, o.refine_points ? 0 : 1);
  for (std::size_t k = 0; k < n; ++k)
    if (flagged(o.constants.points, k)) ch.held[k] = 1;
  const auto long_enough = [&](const Point3D &pt) {
    return sel.min_track_length <= 0 || pt.track.size() >= static_cast<std::size_t>(sel.min_track_length);
  };
  if (sel.images.empty()) {
    for (std::size_t k = 0; k < n; ++k) ch.in[k] = long_enough(model.points[k]);
    return ch;
  }
  ch.config = sel.images;
  // What the config's images refine: their cameras' intrinsics, and their cameras' poses in a rig.
  std::vector<char> camera_config(model.cameras.size(), 0);
  for (const Point3D &pt : model.points) {
    if (!long_enough(pt)) continue;
    for (const TrackElement &e : pt.track) {
      const std::size_t i = at(image_index.at(e.image_id));
      if (ch.config[i]) camera_config[at(camera_index.at(model.images[i].camera_id))] = 1;
    }
  }
  ch.moving.assign(model.images.size(), 0);
  for (std::size_t i = 0; i < model.images.size(); ++i) {
    if (ch.config[i]) continue;
    const std::size_t c = at(camera_index.at(model.images[i].camera_id));
    if (!camera_config[c]) continue;
    const bool intrinsics =
        !flagged(o.constants.intrinsics, c) && !refined_params(o.intrinsics, model.cameras[c].model, false).empty();
    const bool sensor = model.has_rigs && places[i].sensor > 0 && o.poses.sensor_from_rig &&
                        !flagged(o.constants.sensor_from_rig, c);
    ch.moving[i] = intrinsics || sensor;
  }
  for (std::size_t k = 0; k < n; ++k) {
    const Point3D &pt = model.points[k];
    std::size_t in_config = 0;
    for (const TrackElement &e : pt.track) in_config += ch.config[at(image_index.at(e.image_id))] != 0;
    if (!long_enough(pt)) {
      ch.in[k] = 0;
    } else if (flagged(o.constants.points, k)) {
      ch.reach[k] = Chosen::Moving;
    } else if (flagged(sel.variable_points, k)) {
      ch.reach[k] = Chosen::Every;
    } else {
      ch.reach[k] = Chosen::Config;
      ch.in[k] = in_config > 0;
      if (in_config < pt.track.size()) ch.held[k] = 1;  // it is seen beyond the config
    }
  }
  // A point none of whose observations is taken is left out.
  for (std::size_t k = 0; k < n; ++k) {
    if (!ch.in[k]) continue;
    bool taken = false;
    for (const TrackElement &e : model.points[k].track) taken = taken || ch.takes(k, at(image_index.at(e.image_id)));
    ch.in[k] = taken;
  }
  return ch;
}

// The rotation of v by the unit quaternion q (w x y z), and by its inverse.
std::array<double, 3> rotate(const std::array<double, 4> &q, const std::array<double, 3> &v, bool inverse) {
  const double w = q[0], x = inverse ? -q[1] : q[1], y = inverse ? -q[2] : q[2], z = inverse ? -q[3] : q[3];
  // v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z)
  const double cx = y * v[2] - z * v[1], cy = z * v[0] - x * v[2], cz = x * v[1] - y * v[0];
  return {v[0] + 2 * (w * cx + y * cz - z * cy), v[1] + 2 * (w * cy + z * cx - x * cz),
          v[2] + 2 * (w * cz + x * cy - y * cx)};
}

// COLMAP's TWO_CAMS_FROM_WORLD gauge over the draft's holds: the config's images (config, empty:
// every one) that see points, by IMAGE_ID ascending; an image's pose is fixed when its frame's
// pose is held and, in a rig, its camera's pose in the rig too (the reference camera's). Two
// images of different frames fixed already fix the gauge. Otherwise the first image whose
// frame's pose would fix its own (a reference camera, or one whose pose in the rig is held) has
// its frame's pose held, unless one is fixed already, and the next such image of another frame
// has one coordinate of its frame's translation held: the one along which its projection centre
// lies farthest from the first image's, in that image's camera coordinates. False, nothing held,
// when there are no two such images (a rig whose reference camera sees nothing).
bool fix_two_cams(const Model &model, const std::vector<char> &config, Draft *p) {
  const int cnp = p->cnp;
  const int ms = static_cast<int>(p->images.size());
  const auto all_held = [&](int j, int from, int count) {
    const char *f = &p->cam_fixed[at(j) * at(cnp) + at(from)];
    return std::all_of(f, f + count, [](char c) { return c != 0; });
  };
  const auto sensor_held = [&](int j) { return !p->rigged || p->places[at(j)].sensor == 0 || all_held(j, 6, 6); };
  const auto frame_of = [&](int j) { return p->rigged ? p->places[at(j)].frame : at(j); };
  std::vector<int> order;
  for (int j = 0; j < ms; ++j)
    if (config.empty() || config[at(p->images[at(j)])]) order.push_back(j);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    return model.images[at(p->images[at(a)])].id < model.images[at(p->images[at(b)])].id;
  });
  int anchor = -1, second = -1;
  bool anchor_fixed = false;
  for (const int j : order) {
    if (!all_held(j, 0, 6) || !sensor_held(j)) continue;
    if (anchor < 0) {
      anchor = j;
      anchor_fixed = true;
    } else if (frame_of(j) != frame_of(anchor)) {
      return true;  // two fixed already
    }
  }
  for (const int j : order) {
    if (!sensor_held(j) || (anchor >= 0 && frame_of(j) == frame_of(anchor))) continue;
    if (anchor < 0) {
      anchor = j;
    } else {
      second = j;
      break;
    }
  }
  if (anchor < 0 || second < 0) return false;
  // The anchor's pose (cam_from_world) and the second frame's, at the start.
  const auto image_pose = [&](int j, std::array<double, 4> *q, std::array<double, 3> *t) {
    if (!p->rigged) {
      const cc::Camera &c = p->cameras[at(j)];
      *q = {c.q.w, c.q.x, c.q.y, c.q.z};
      *t = c.t;
      return;
    }
    const cc::RigImage &r = p->rig_images[at(j)];
    *q = {r.q_frame.w, r.q_frame.x, r.q_frame.y, r.q_frame.z};
    *t = r.t_frame;
    if (p->places[at(j)].sensor == 0) return;
    // sensor_from_rig * rig_from_world
    const std::array<double, 4> s{r.q_sensor.w, r.q_sensor.x, r.q_sensor.y, r.q_sensor.z};
    const std::array<double, 3> rt = rotate(s, *t, false);
    *t = {rt[0] + r.t_sensor[0], rt[1] + r.t_sensor[1], rt[2] + r.t_sensor[2]};
    const std::array<double, 4> f = *q;
    *q = {s[0] * f[0] - s[1] * f[1] - s[2] * f[2] - s[3] * f[3], s[0] * f[1] + s[1] * f[0] + s[2] * f[3] - s[3] * f[2],
          s[0] * f[2] - s[1] * f[3] + s[2] * f[0] + s[3] * f[1], s[0] * f[3] + s[1] * f[2] - s[2] * f[1] + s[3] * f[0]};
  };
  std::array<double, 4> qa, qb;
  std::array<double, 3> ta, tb;
  image_pose(anchor, &qa, &ta);
  if (p->rigged) {
    const cc::RigImage &r = p->rig_images[at(second)];
    qb = {r.q_frame.w, r.q_frame.x, r.q_frame.y, r.q_frame.z};
    tb = r.t_frame;
  } else {
    image_pose(second, &qb, &tb);
  }
  const std::array<double, 3> rb = rotate(qb, tb, true);
  const std::array<double, 3> v = rotate(qa, {-rb[0], -rb[1], -rb[2]}, false);
  int k = 0;
  for (int c = 1; c < 3; ++c)
    if (std::abs(v[at(c)] + ta[at(c)]) > std::abs(v[at(k)] + ta[at(k)])) k = c;
  for (int j = 0; j < ms; ++j) {
    char *fixed = &p->cam_fixed[at(j) * at(cnp)];
    if (!anchor_fixed && frame_of(j) == frame_of(anchor)) std::fill_n(fixed, 6, 1);
    if (frame_of(j) == frame_of(second)) fixed[3 + k] = 1;
  }
  return true;
}

// COLMAP's THREE_POINTS gauge over the chosen points: unless three points of the problem are held
// already, the refined ones seen by the most of its observations (the first in the model's order
// among equals) are held until three are, as constant points.
void fix_three_points(const Model &model, const std::unordered_map<std::uint32_t, int> &image_index, Chosen *ch) {
  const std::size_t n = model.points.size();
  std::size_t held = 0;
  std::vector<std::pair<std::size_t, std::size_t>> free;  // (observations taken, point)
  for (std::size_t k = 0; k < n; ++k) {
    if (!ch->in[k]) continue;
    if (ch->held[k]) {
      ++held;
      continue;
    }
    std::size_t taken = 0;
    for (const TrackElement &e : model.points[k].track) taken += ch->takes(k, at(image_index.at(e.image_id)));
    free.push_back({taken, k});
  }
  std::stable_sort(free.begin(), free.end(), [](const auto &a, const auto &b) { return a.first > b.first; });
  for (std::size_t q = 0; held < 3 && q < free.size(); ++q, ++held) {
    const std::size_t k = free[q].second;
    ch->held[k] = 1;
    // COLMAP makes the gauge's points constant points: a variable point's observations in images
    // outside the config with nothing refined leave the problem (constant terms), unless none
    // would be left.
    if (ch->reach[k] != Chosen::Every) continue;
    ch->reach[k] = Chosen::Moving;
    bool taken = false;
    for (const TrackElement &e : model.points[k].track) taken = taken || ch->takes(k, at(image_index.at(e.image_id)));
    if (!taken) ch->reach[k] = Chosen::Every;
  }
}

// The order of the problem's points (Draft::point_order) and how many lead it held
// (held_points): without a selection or held points, the model's order and ncon as given;
// otherwise the first ncon points and the held ones, in the model's order, then the others, each
// point the selection takes.
void order_points(const Model &model, const Chosen &ch, bool selects, int ncon, Draft *p) {
  p->held_points = ncon;
  const std::size_t n = model.points.size();
  const bool any_held = std::any_of(ch.held.begin(), ch.held.end(), [](char c) { return c != 0; });
  if (!selects && !any_held) return;
  if (!selects && ncon >= static_cast<int>(n)) return;  // every point held, or a --ncon the solve refuses
  int k = 0;  // the point's place among those the selection takes
  std::vector<int> first, rest;
  for (std::size_t i = 0; i < n; ++i) {
    if (!ch.in[i]) continue;
    (k++ < ncon || ch.held[i] ? first : rest).push_back(static_cast<int>(i));
  }
  p->held_points = static_cast<int>(first.size());
  p->point_order = std::move(first);
  p->point_order.insert(p->point_order.end(), rest.begin(), rest.end());
}

// The problem's points and their projections (Draft::points) in the order of
// order_points; camera_of: each image's sba camera, image_index: an IMAGE_ID's image.
void problem_points(const Model &model, const Chosen &ch, const std::unordered_map<std::uint32_t, int> &image_index,
                    const std::vector<int> &camera_of, Draft *p) {
  const int n = p->point_order.empty() ? static_cast<int>(model.points.size()) : static_cast<int>(p->point_order.size());
  eucsba::PointSet &s = p->points;
  s.ncameras = static_cast<int>(p->images.size());
  s.xyz.reserve(at(n) * 3);
  std::vector<std::pair<int, const Point2D *>> track;
  for (int k = 0; k < n; ++k) {
    const std::size_t index = p->point_order.empty() ? at(k) : at(p->point_order[at(k)]);
    const Point3D &pt = model.points[index];
    s.xyz.insert(s.xyz.end(), pt.xyz.begin(), pt.xyz.end());
    track.clear();
    for (const TrackElement &e : pt.track) {
      const int j = image_index.at(e.image_id);
      if (!ch.takes(index, at(j))) continue;
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

// The draft of a model: its sba cameras, holds, groups and points.
bool draft_of(const Model &model, const Options &o, const std::string &name, Draft *out, std::string *error) {
  std::unordered_map<std::uint32_t, int> camera_index, image_index;
  for (std::size_t c = 0; c < model.cameras.size(); ++c) camera_index.emplace(model.cameras[c].id, static_cast<int>(c));
  const int m = static_cast<int>(model.images.size());
  if (m == 0 || model.points.empty()) {
    *error = name + ": the model has no images or no points";
    return false;
  }
  for (int j = 0; j < m; ++j) image_index.emplace(model.images[at(j)].id, j);
  Draft p;
  if (model.has_rigs) p.image_places = image_places(model);
  Chosen ch = choose(model, o, image_index, camera_index, p.image_places);
  // An image is a camera of the problem when it sees a point the problem takes (without a
  // selection every point, each seen: check_model).
  std::vector<int> camera_of(at(m), -1);
  for (std::size_t k = 0; k < model.points.size(); ++k) {
    if (!ch.in[k]) continue;
    for (const TrackElement &e : model.points[k].track) {
      const std::size_t i = at(image_index.at(e.image_id));
      if (ch.takes(k, i)) camera_of[i] = 0;
    }
  }
  for (int j = 0; j < m; ++j)
    if (camera_of[at(j)] >= 0) {
      camera_of[at(j)] = static_cast<int>(p.images.size());
      p.images.push_back(j);
    }
  if (p.images.empty()) {
    *error = name + ": the configuration leaves no observation to refine";
    return false;
  }
  const bool frames_held = !o.selection.images.empty() ||
                           std::any_of(o.constants.frames.begin(), o.constants.frames.end(), [](char c) { return c != 0; });
  if (refined_as_rigs(model, o.poses, frames_held, p.image_places))
    rig_problem(model, o.intrinsics, o.poses, o.constants, ch.config, o.mcon, camera_index, &p);
  else
    image_problem(model, o.intrinsics, o.poses, o.constants, ch.config, o.mcon, camera_index, &p);
  if (o.gauge == Gauge::TwoCamsFromWorld && fix_two_cams(model, ch.config, &p)) {
    p.counts.gauge = Gauge::TwoCamsFromWorld;
  } else if (o.gauge != Gauge::None) {
    fix_three_points(model, image_index, &ch);
    p.counts.gauge = Gauge::ThreePoints;
  }
  order_points(model, ch, o.selection.active() || o.gauge == Gauge::ThreePoints, o.ncon, &p);
  problem_points(model, ch, image_index, camera_of, &p);
  *out = std::move(p);
  return true;
}

// Writes a refined pose over *out: the rotation unless its 3 parameters are all held, the
// translation unless its 3 are, so that a held part keeps the bits it was read with (the
// parametrization's round trip would move them). Whether anything was written.
bool write_pose(const char *fixed, const sbacameras::euclidean::Quaternion &q, const std::array<double, 3> &t,
                Pose *out) {
  const auto held = [](const char *f) { return f[0] && f[1] && f[2]; };
  if (!held(fixed)) out->q = {q.w, q.x, q.y, q.z};
  if (!held(fixed + 3)) out->t = t;
  return !held(fixed) || !held(fixed + 3);
}

// The parameters of COLMAP camera `cam` that sba camera j of sm refines (fixed: its cnp flags)
// from params, its model's parameters.
void write_params(const cc::SbaCameraModel &sm, int j, const char *fixed, const std::vector<double> &params,
                  Camera *cam) {
  for (std::size_t k = 0; k < cam->params.size(); ++k)
    if (const int c = sm.param_column(j, static_cast<int>(k)); c >= 0 && !fixed[c]) cam->params[k] = params[k];
}

// A model's records by id, for apply.
template <typename Record>
std::unordered_map<std::uint64_t, Record *> index_of(std::vector<Record> &records) {
  std::unordered_map<std::uint64_t, Record *> index;
  index.reserve(records.size());
  for (Record &r : records) index.emplace(r.id, &r);
  return index;
}

template <typename Record>
Record &find(const std::unordered_map<std::uint64_t, Record *> &index, std::uint64_t id, const char *what) {
  const auto it = index.find(id);
  if (it == index.end())
    throw std::invalid_argument(std::string("the model has no ") + what + " " + std::to_string(id) +
                                " of the problem's");
  return *it->second;
}

}  // namespace

struct Problem::Builder {
  // The ids of each sba camera of d, built of model, into out.
  static void ids(const Model &model, const Draft &d, Problem *out) {
    std::vector<char> params_written(model.cameras.size(), 0);
    std::unordered_map<std::uint32_t, std::size_t> camera_index;
    for (std::size_t c = 0; c < model.cameras.size(); ++c) camera_index.emplace(model.cameras[c].id, c);
    const std::vector<ImagePlace> &places = d.image_places;
    for (std::size_t j = 0; j < d.images.size(); ++j) {
      const Image &im = model.images[at(d.images[j])];
      CameraIds r;
      r.image = im.id;
      r.camera = im.camera_id;
      if (model.has_rigs) {
        const ImagePlace &pl = places[at(d.images[j])];
        r.frame = model.frames[pl.frame].id;
        r.rig = model.rigs[pl.rig].id;
        r.reference = pl.sensor == 0;
      }
      char &written = params_written[camera_index.at(im.camera_id)];
      // Below mcon nothing is written; from mcon on, the first of a camera's images writes it.
      r.writes_params = static_cast<int>(j) >= out->mcon_ && !written;
      if (r.writes_params) written = 1;
      out->ids_.push_back(r);
    }
    if (d.point_order.empty())
      for (const Point3D &pt : model.points) out->point_ids_.push_back(pt.id);
    for (const int k : d.point_order) out->point_ids_.push_back(model.points[at(k)].id);
  }
};

template <typename F>
decltype(auto) Problem::with_model(F f) const {
  return rig_model_ ? f(*rig_model_) : f(*image_model_);
}

bool Problem::build(const Model &model, const Options &options, const std::string &name, Problem *out,
                    std::string *error) {
  Draft d;
  if (!draft_of(model, options, name, &d, error)) return false;
  Problem p;
  p.mcon_ = options.mcon;
  p.has_rigs_ = model.has_rigs;
  try {
    if (d.rigged)
      p.rig_model_ = std::make_unique<cc::RigCameraModel>(d.rig_images, d.points.xyz, d.cam_fixed, d.kept);
    else
      p.image_model_ = std::make_unique<cc::CameraModel>(d.cameras, d.points.xyz, d.cam_fixed, d.kept);
  } catch (const std::invalid_argument &e) {
    *error = name + ": " + e.what();
    return false;
  }
  p.p0_ = p.with_model([](const auto &sm) {
    std::vector<double> p0 = sm.initial_camera_params();
    p0.insert(p0.end(), sm.initial_points().begin(), sm.initial_points().end());
    return p0;
  });
  Builder::ids(model, d, &p);
  p.images_ = std::move(d.images);
  p.points_ = std::move(d.points);
  // COLMAP 4 costs an observation whose point its projection refuses (behind the camera)
  // nothing; the models do so given the measurements, whose buffer moves with the problem.
  if (p.rig_model_)
    p.rig_model_->set_measurements(p.points_.x.data());
  else
    p.image_model_->set_measurements(p.points_.x.data());
  p.cnp_ = d.cnp;
  p.held_points_ = d.held_points;
  p.rigged_ = d.rigged;
  p.cam_fixed_ = std::move(d.cam_fixed);
  p.cam_param_group_ = std::move(d.cam_param_group);
  p.counts_ = d.counts;
  *out = std::move(p);
  return true;
}

Problem::Problem() = default;
Problem::Problem(Problem &&) noexcept = default;
Problem &Problem::operator=(Problem &&) noexcept = default;
Problem::~Problem() = default;

Problem::Callback Problem::func() const { return rigged_ ? cc::rig_motstr_func : cc::motstr_func; }
Problem::Callback Problem::fjac() const { return rigged_ ? cc::rig_motstr_fjac : cc::motstr_fjac; }
void *Problem::adata() const {
  return with_model([](const auto &sm) { return cc::as_adata(sm); });
}

bool Problem::project(const double *p, int j, int i, double x[2]) const {
  const std::size_t m = images_.size();
  return with_model([&](const auto &sm) {
    return sm.project(j, p + at(j) * at(cnp_), p + m * at(cnp_) + 3 * at(i), x);
  });
}

std::function<bool(const double *p, int j, int i, double x[2])> Problem::cached_project() const {
  const std::size_t m = images_.size(), cnp = at(cnp_);
  return with_model([&](const auto &sm) -> std::function<bool(const double *, int, int, double *)> {
    auto cache = std::make_shared<cc::CachedProjection<std::decay_t<decltype(sm)>>>(sm);
    return [cache, m, cnp](const double *p, int j, int i, double x[2]) {
      return cache->project(j, p + at(j) * cnp, p + m * cnp + 3 * at(i), x);
    };
  });
}

std::vector<cc::Camera> Problem::cameras(const double *p) const {
  std::vector<cc::Camera> out;
  for (int j = 0; j < ncameras(); ++j)
    out.push_back(with_model([&](const auto &sm) { return sm.camera(j, p + at(j) * at(cnp_)); }));
  return out;
}

std::string Problem::nonfinite_error(const Model &model, const std::string &name) const {
  const eucsba::PointSet &s = points_;
  // Every projection through the solve's own callback, which sets each camera up once: one
  // COLMAP refuses comes back as its measurement, at no cost, as the solve will cost it.
  const int nobs = s.nprojections(), n = npoints();
  std::vector<int> rowptr(at(n) + 1, 0), colidx(s.pairs.camera), val(at(nobs));
  for (int k = 0; k < nobs; ++k) {
    ++rowptr[at(s.pairs.point[at(k)]) + 1];
    val[at(k)] = k;
  }
  std::partial_sum(rowptr.begin(), rowptr.end(), rowptr.begin());
  sba_crsm idx{n, ncameras(), nobs, val.data(), colidx.data(), rowptr.data()};
  std::vector<double> hx(2 * at(nobs));
  func()(const_cast<double *>(p0_.data()), &idx, nullptr, nullptr, hx.data(), adata());
  for (std::size_t k = 0; k < s.pairs.size(); ++k) {
    const double dx = hx[2 * k] - s.x[2 * k], dy = hx[2 * k + 1] - s.x[2 * k + 1];
    if (std::isfinite(dx * dx + dy * dy)) continue;
    const int i = s.pairs.point[k], j = s.pairs.camera[k];
    double x[2];
    project(p0_.data(), j, i, x);
    const Image &im = model.images[at(images_[at(j)])];
    const auto camera = std::find_if(model.cameras.begin(), model.cameras.end(),
                                     [&](const Camera &c) { return c.id == im.camera_id; });
    char pixels[64];
    std::snprintf(pixels, sizeof pixels, "(%g, %g)", x[0], x[1]);
    const std::string image_name = quoted(im.name);  // its control characters as \xHH, in quotes
    return name + ": image " + std::to_string(im.id) + " (" + image_name.substr(1, image_name.size() - 2) +
           "), camera " + std::to_string(im.camera_id) + " (" + camera_model_name(camera->model) + "): point " +
           std::to_string(point_ids_[at(i)]) + " projects to " + pixels +
           " px, where its squared reprojection error is not finite";
  }
  return {};
}

// The records of the model apply writes into, by id.
struct Problem::Index {
  explicit Index(Model *model)
      : cameras(index_of(model->cameras)),
        images(index_of(model->images)),
        points(index_of(model->points)),
        frames(index_of(model->frames)),
        rigs(index_of(model->rigs)) {}
  std::unordered_map<std::uint64_t, Camera *> cameras;
  std::unordered_map<std::uint64_t, Image *> images;
  std::unordered_map<std::uint64_t, Point3D *> points;
  std::unordered_map<std::uint64_t, Frame *> frames;
  std::unordered_map<std::uint64_t, Rig *> rigs;
};

namespace {

// The pose in rig `rig` of camera `camera`, not the rig's reference.
Pose &sensor_pose(Rig &rig, std::uint32_t camera) {
  const auto s = std::find_if(rig.sensors.begin(), rig.sensors.end(), [&](const RigSensor &x) {
    return x.sensor.type == SensorType::Camera && x.sensor.id == camera;
  });
  if (s == rig.sensors.end())
    throw std::invalid_argument("rig " + std::to_string(rig.id) + " has no camera " + std::to_string(camera));
  return s->sensor_from_rig;
}

}  // namespace

void Problem::write_image(int j, const double *a, const Index &index) const {
  const CameraIds &r = ids_[at(j)];
  const char *fixed = &cam_fixed_[at(j) * at(cnp_)];
  const cc::Camera c = image_model_->camera(j, a);
  if (!has_rigs_) {
    Image &im = find(index.images, r.image, "image");
    Pose pose{im.q, im.t};
    write_pose(fixed, c.q, c.t, &pose);
    im.q = pose.q;
    im.t = pose.t;
  } else if (Pose pose; write_pose(fixed, c.q, c.t, &pose)) {
    // The image's pose is derived from its frame, of this image alone (build), which takes the
    // refined pose. Both parts of it are refined, or both held. The image's q and t, the images
    // file's rendering of its pose, take the refined pose's bits, which the frame composes to
    // but for rounding, so that the file holds the pose the solve found (image_poses).
    find(index.frames, r.frame, "frame").rig_from_world =
        frame_pose(pose, r.reference ? nullptr : &sensor_pose(find(index.rigs, r.rig, "rig"), r.camera));
    Image &im = find(index.images, r.image, "image");
    im.q = pose.q;
    im.t = pose.t;
  }
  if (r.writes_params) write_params(*image_model_, j, fixed, c.params, &find(index.cameras, r.camera, "camera"));
}

void Problem::write_rig_image(int j, const double *a, const Index &index,
                              std::unordered_map<std::uint32_t, char> *frames_done) const {
  const CameraIds &r = ids_[at(j)];
  const char *fixed = &cam_fixed_[at(j) * at(cnp_)];
  const cc::RigImage im = rig_model_->image(j, a);
  // Each frame, camera pose in a rig and COLMAP camera is written once, from its first sba
  // camera: all of them hold the same values.
  if (char &done = (*frames_done)[r.frame]; !done) {
    done = 1;
    write_pose(fixed, im.q_frame, im.t_frame, &find(index.frames, r.frame, "frame").rig_from_world);
  }
  if (!r.writes_params) return;
  if (!r.reference)
    write_pose(fixed + 6, im.q_sensor, im.t_sensor, &sensor_pose(find(index.rigs, r.rig, "rig"), r.camera));
  write_params(*rig_model_, j, fixed, im.params, &find(index.cameras, r.camera, "camera"));
}

void Problem::write_points(const double *p, const Index &index, bool errors) const {
  const std::size_t m = images_.size();
  std::unordered_map<std::uint32_t, int> camera_of;  // an image's sba camera
  for (std::size_t j = 0; j < m; ++j) camera_of.emplace(ids_[j].image, static_cast<int>(j));
  const double *points = p + m * at(cnp_);
  std::function<bool(const double *, int, int, double *)> project;
  if (errors) project = cached_project();
  for (std::size_t k = at(held_points_); k < point_ids_.size(); ++k) {
    Point3D &pt = find(index.points, point_ids_[k], "point");
    const double *b = points + 3 * k;
    for (int c = 0; c < 3; ++c) pt.xyz[at(c)] = b[c];
    if (!errors) continue;
    double sum = 0;
    for (const TrackElement &e : pt.track) {
      const int j = camera_of.at(e.image_id);
      const Point2D &obs = find(index.images, e.image_id, "image").points[e.point2d_idx];
      double x[2];
      // COLMAP's error of an observation its projection refuses is the root of the largest
      // double, so that its filters remove the point.
      if (project(p, j, static_cast<int>(k), x))
        sum += std::hypot(x[0] - obs.x, x[1] - obs.y);
      else
        sum += std::sqrt(DBL_MAX);
    }
    pt.error = sum / static_cast<double>(pt.track.size());
  }
}

void Problem::apply(const double *p, Model *model, bool errors) const {
  const Index index(model);
  std::unordered_map<std::uint32_t, char> frames_done;
  for (int j = mcon_; j < ncameras(); ++j) {
    const double *a = p + at(j) * at(cnp_);
    if (rigged_)
      write_rig_image(j, a, index, &frames_done);
    else
      write_image(j, a, index);
  }
  write_points(p, index, errors);
}

bool Problem::covariance(const Model &model, const double *p, const sba_ext_options &ext,
                         const CovarianceOptions &options, Covariances *out) const {
  const int m = ncameras(), n = npoints();
  std::vector<int> cams(at(m)), pts(options.points ? at(n - held_points_) : 0);
  std::iota(cams.begin(), cams.end(), 0);
  std::iota(pts.begin(), pts.end(), held_points_);
  std::vector<double> camcov(at(m) * at(cnp_) * at(cnp_)), ptcov(pts.size() * 9);
  sba_covariance_request req;
  sba_covariance_request_init(&req);
  req.ncams = m;
  req.cams = cams.data();
  req.camcov = camcov.data();
  req.npts = static_cast<int>(pts.size());
  req.pts = pts.data();
  req.ptcov = ptcov.data();
  req.unscaled = 1;
  req.point_damping = options.point_damping;
  sba_ext_options e = ext;
  e.cam_fixed = cam_fixed_.data();
  e.cam_fixed_per_camera = 1;
  e.cam_group = nullptr;
  e.cam_shared = nullptr;
  e.cam_param_group = cam_param_group_.data();
  // The library reads p and x without changing them, but takes them as non-const.
  std::vector<double> pc(p, p + at(m) * at(cnp_) + 3 * at(n));
  const sba_visibility vis{static_cast<long long>(points_.pairs.size()), points_.pairs.point.data(),
                           points_.pairs.camera.data()};
  if (sba_motstr_covariance_x_vis(n, held_points_, m, mcon_, &vis, pc.data(), cnp_, 3,
                                  const_cast<double *>(points_.x.data()), nullptr, 2, func(), fjac(), adata(), &req,
                                  &e) != 0)
    return false;
  *out = Covariances();
  out->sigma2 = req.sigma2;
  out->rank = req.rank;
  out->nfree = req.nfree;
  pose_covariances(model, pc.data(), camcov.data(), out);
  camera_covariances(camcov.data(), out);
  for (std::size_t q = 0; q < pts.size(); ++q) {
    CovarianceBlock b = param_covariance(ptcov.data() + 9 * q, nullptr, 3, 0, 3);
    b.id = point_ids_[at(pts[q])];
    out->points.push_back(std::move(b));
  }
  return true;
}

void Problem::pose_covariances(const Model &model, const double *p, const double *camcov, Covariances *out) const {
  std::vector<std::uint32_t> frames_done;
  for (int j = mcon_; j < ncameras(); ++j) {
    const CameraIds &r = ids_[at(j)];
    const double *a = p + at(j) * at(cnp_), *cov = camcov + at(j) * at(cnp_) * at(cnp_);
    const char *fixed = &cam_fixed_[at(j) * at(cnp_)];
    if (!rigged_) {
      CovarianceBlock b = pose_covariance(a, cov, fixed, cnp_, 0);
      b.id = r.image;
      b.name = model.images[at(images_[at(j)])].name;
      if (!b.coords.empty()) out->images.push_back(std::move(b));
      continue;
    }
    const cc::RigImage im = rig_model_->image(j, a);
    double R_s[9];
    sbacameras::euclidean::rotation_matrix(im.q_sensor, R_s);
    CovarianceBlock c = composed_pose_covariance(a, cov, fixed, cnp_, R_s, im.t_frame.data());
    c.id = r.image;
    c.name = model.images[at(images_[at(j)])].name;
    if (!c.coords.empty()) out->images.push_back(std::move(c));
    // A frame's pose and a camera's pose in its rig are one each, whichever image holds them.
    if (std::find(frames_done.begin(), frames_done.end(), r.frame) == frames_done.end()) {
      frames_done.push_back(r.frame);
      CovarianceBlock b = pose_covariance(a, cov, fixed, cnp_, 0);
      b.id = r.frame;
      if (!b.coords.empty()) out->frames.push_back(std::move(b));
    }
    if (r.writes_params && !r.reference) {
      CovarianceBlock b = pose_covariance(a, cov, fixed, cnp_, cc::kPoseParams);
      b.id = r.camera;
      if (!b.coords.empty()) out->sensors.push_back(std::move(b));
    }
  }
}

void Problem::camera_covariances(const double *camcov, Covariances *out) const {
  for (int j = mcon_; j < ncameras(); ++j) {
    const CameraIds &r = ids_[at(j)];
    if (!r.writes_params) continue;
    const int count = static_cast<int>(
        rigged_ ? rig_model_->input_image(j).params.size() : image_model_->input_camera(j).params.size());
    int columns[cc::kMaxParams];
    with_model([&](const auto &sm) {
      for (int k = 0; k < count; ++k) columns[k] = sm.param_column(j, k);
    });
    CovarianceBlock b =
        param_covariance(camcov + at(j) * at(cnp_) * at(cnp_), &cam_fixed_[at(j) * at(cnp_)], cnp_, columns, count);
    b.id = r.camera;
    if (!b.coords.empty()) out->cameras.push_back(std::move(b));
  }
}

// ---- priors ----

void Problem::centre(int j, const double *a, double c[3], double *J) const {
  const auto centre_at = [&](const double *aj, double out[3]) {
    const cc::Camera cam = with_model([&](const auto &sm) { return sm.camera(j, aj); });
    double R[9];
    sbacameras::euclidean::rotation_matrix(cam.q, R);
    for (int r = 0; r < 3; ++r) out[r] = -(R[r] * cam.t[0] + R[3 + r] * cam.t[1] + R[6 + r] * cam.t[2]);
  };
  centre_at(a, c);
  if (!J) return;
  const int np = rigged_ ? cc::kRigPoseParams : cc::kPoseParams;
  std::fill(J, J + 3 * at(cnp_), 0.0);
  std::vector<double> x(a, a + cnp_);
  for (int k = 0; k < np; ++k) {
    if (held(j, k)) continue;
    // The rotation parameters are small angles and the translations lengths: a step relative
    // to the value, at least 1e-6, leaves both the truncation (a centre is quadratic at most
    // in them) and the rounding near 1e-10 of the centre.
    const double h = 1e-6 * std::max(1.0, std::fabs(a[k]));
    double plus[3], minus[3];
    x[at(k)] = a[k] + h;
    centre_at(x.data(), plus);
    x[at(k)] = a[k] - h;
    centre_at(x.data(), minus);
    x[at(k)] = a[k];
    for (int r = 0; r < 3; ++r) J[at(r) * at(cnp_) + at(k)] = (plus[r] - minus[r]) / (2 * h);
  }
}

bool Problem::camera_parameter(std::uint32_t camera_id, int k, int *j, int *column) const {
  for (std::size_t q = 0; q < ids_.size(); ++q)
    if (ids_[q].camera == camera_id && ids_[q].writes_params) {
      *j = static_cast<int>(q);
      *column = k < 0 || k >= cc::kMaxParams ? -1 : with_model([&](const auto &sm) { return sm.param_column(*j, k); });
      return true;
    }
  return false;
}

void ProblemPriors::residual(int j, const double *aj, double *r, void *data) {
  const Position &p = *static_cast<const Position *>(data);
  p.problem->centre(j, aj, r, nullptr);
  for (int k = 0; k < 3; ++k) r[k] -= p.mean[at(k)];
}

void ProblemPriors::jacobian(int j, const double *aj, double *jac, void *data) {
  const Position &p = *static_cast<const Position *>(data);
  double c[3];
  p.problem->centre(j, aj, c, jac);
}

bool ProblemPriors::build(const Problem &problem, const std::vector<PosePrior> &poses, const PosePriorOptions &options,
                          const std::vector<PointPrior> &points, const std::vector<IntrinsicPrior> &intrinsics,
                          std::string *error) {
  positions_.clear();
  linears_.clear();
  points_.clear();
  camera_.clear();
  linear_.clear();
  point_.clear();
  loss_ = options.loss;
  const int np = problem.rigged() ? cc::kRigPoseParams : cc::kPoseParams;
  std::unordered_map<std::uint32_t, int> camera_of;  // IMAGE_ID: sba camera
  for (int j = 0; j < problem.ncameras(); ++j) camera_of.emplace(problem.image_id(j), j);
  for (const PosePrior &pp : poses) {
    const auto found = camera_of.find(pp.image_id);
    if (found == camera_of.end()) continue;
    const int j = found->second;
    bool free = false;
    for (int k = 0; k < np; ++k) free = free || !problem.held(j, k);
    if (!free || j < problem.mcon()) continue;
    positions_.push_back({&problem, j, pp.position, pp.covariance});
  }
  std::unordered_map<std::uint64_t, int> point_of;  // POINT3D_ID: problem point
  if (!points.empty())
    for (int i = 0; i < problem.npoints(); ++i) point_of.emplace(problem.point_id(i), i);
  for (const PointPrior &gp : points) {
    const auto found = point_of.find(gp.point_id);
    const int i = found == point_of.end() ? -1 : found->second;
    if (i < 0) {
      *error = gp.where + ": point " + std::to_string(gp.point_id) + " is not in the problem";
      return false;
    }
    if (i < problem.held_points()) {
      *error = gp.where + ": point " + std::to_string(gp.point_id) + " is held (a constant point): a prior on it "
                          "cannot move it";
      return false;
    }
    points_.push_back({i, gp.position, gp.covariance});
  }
  for (const IntrinsicPrior &ip : intrinsics) {
    int j = -1, column = -1;
    if (!problem.camera_parameter(ip.camera_id, ip.param, &j, &column)) {
      *error = ip.where + ": camera " + std::to_string(ip.camera_id) + " is refined in no image (none of its images "
                          "sees a point, or all are held by --mcon)";
      return false;
    }
    if (problem.held(j, column)) {
      *error = ip.where + ": parameter " + std::to_string(ip.param) + " of camera " + std::to_string(ip.camera_id) +
               " is held (--intrinsics, --refine-*, --hold-intrinsics): a prior on it cannot move it";
      return false;
    }
    linears_.push_back({j, column, ip.mean, ip.stddev});
  }
  make_structs(options.loss_scale);
  return true;
}

void ProblemPriors::make_structs(double loss_scale) {
  const char *loss = loss_.empty() ? nullptr : loss_.c_str();
  for (const Position &p : positions_) {
    sba_camera_prior c{};
    c.camera = p.j;
    c.dim = 3;
    c.func = residual;
    c.jacf = jacobian;
    c.data = const_cast<Position *>(&p);
    c.weight.covariance = p.covariance.data();
    c.loss = loss;
    c.loss_scale = loss_scale;
    camera_.push_back(c);
  }
  for (const Linear &p : linears_) {
    sba_camera_linear_prior l{};
    l.camera = p.j;
    l.k = 1;
    l.params = &p.param;
    l.mean = &p.mean;
    l.weight.sigma = &p.sigma;
    linear_.push_back(l);
  }
  for (const Point &p : points_) {
    sba_point_prior q{};
    q.point = p.i;
    q.mean = p.mean.data();
    q.weight.covariance = p.covariance.data();
    point_.push_back(q);
  }
}

void ProblemPriors::attach(sba_ext_options *ext) const {
  ext->ncamera_priors = static_cast<int>(camera_.size());
  ext->camera_priors = camera_.empty() ? nullptr : camera_.data();
  ext->ncamera_linear_priors = static_cast<int>(linear_.size());
  ext->camera_linear_priors = linear_.empty() ? nullptr : linear_.data();
  ext->npoint_priors = static_cast<int>(point_.size());
  ext->point_priors = point_.empty() ? nullptr : point_.data();
}

}  // namespace sbaformats::colmap
