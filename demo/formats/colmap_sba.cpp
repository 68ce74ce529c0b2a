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

bool to_sba(const Model &model, const RefineIntrinsics &refine, const std::vector<char> &held_pose, int mcon,
            const std::string &name, ColmapProblem *out, std::string *error) {
  const std::string where = name + ": ";
  std::unordered_map<std::uint32_t, int> camera_index, image_index;
  for (std::size_t c = 0; c < model.cameras.size(); ++c) camera_index.emplace(model.cameras[c].id, static_cast<int>(c));
  const int m = static_cast<int>(model.images.size());
  const int n = static_cast<int>(model.points.size());
  if (m == 0 || n == 0) return fail(error, where + "the model has no images or no points");
  // Each image's pose is a free unknown: the images of a frame would leave their rig's shape.
  if (model.has_rigs)
    for (const Frame &f : model.frames) {
      const auto images = std::count_if(f.data.begin(), f.data.end(),
                                        [](const DataId &d) { return d.sensor.type == SensorType::Camera; });
      if (images > 1)
        return fail(error, where + "frame " + std::to_string(f.id) + " holds " + std::to_string(images) +
                               " images (rig " + std::to_string(f.rig_id) +
                               "): rigs of several cameras are not refined yet");
    }
  for (int j = 0; j < m; ++j) image_index.emplace(model.images[at(j)].id, j);
  // An image is a camera of the problem when it sees a point (every point is seen: check_model).
  std::vector<int> camera_of(at(m), -1);
  for (const Point3D &pt : model.points)
    for (const TrackElement &e : pt.track) camera_of[at(image_index.at(e.image_id))] = 0;
  ColmapProblem p;
  int np = 0;
  for (int j = 0; j < m; ++j) {
    if (camera_of[at(j)] < 0) continue;
    const Image &im = model.images[at(j)];
    const Camera &c = model.cameras[at(camera_index.at(im.camera_id))];
    camera_of[at(j)] = static_cast<int>(p.cameras.size());
    cc::Camera cam;
    cam.model = c.model;
    cam.params = c.params;
    cam.q = {im.q[0], im.q[1], im.q[2], im.q[3]};
    for (int k = 0; k < 3; ++k) cam.t[at(k)] = im.t[at(k)];
    np = std::max(np, cc::param_count(c.model));
    p.cameras.push_back(std::move(cam));
    p.images.push_back(j);
  }
  const int ms = static_cast<int>(p.cameras.size());
  const int cnp = p.cnp = cc::camera_params(np);
  // Each COLMAP camera's sba cameras; one below mcon holds the camera's parameters in all.
  std::vector<std::vector<int>> users(model.cameras.size());
  for (int j = 0; j < ms; ++j) users[at(camera_index.at(model.images[at(p.images[at(j)])].camera_id))].push_back(j);
  p.cam_fixed.assign(at(ms) * at(cnp), 0);
  p.cam_group.assign(at(ms), -1);
  p.cam_shared.assign(at(cnp), 0);
  for (int k = cc::kPoseParams; k < cnp; ++k) p.cam_shared[at(k)] = 1;
  for (std::size_t c = 0; c < users.size(); ++c) {
    const std::vector<int> &u = users[c];
    if (u.empty()) continue;
    const bool below_mcon = u.front() < mcon;  // u ascends
    const int model_id = model.cameras[c].model, count = cc::param_count(model_id);
    for (int j : u) {
      char *fixed = &p.cam_fixed[at(j) * at(cnp)];
      for (int k = 0; k < cnp - cc::kPoseParams; ++k) {
        bool held = below_mcon || k >= count;
        if (!held) switch (cc::param_kind(model_id, k)) {
            case cc::ParamKind::Focal: held = !refine.focal; break;
            case cc::ParamKind::Principal: held = !refine.principal; break;
            case cc::ParamKind::Extra: held = !refine.distortion; break;
            case cc::ParamKind::Size: held = true; break;  // no COLMAP option refines it
          }
        fixed[cc::kPoseParams + k] = held ? 1 : 0;
      }
      if (u.size() > 1 && !below_mcon) p.cam_group[at(j)] = u.front();
    }
    if (u.size() > 1 && !below_mcon) ++p.shared_cameras;
  }
  for (int j = 0; j < ms; ++j)
    if (!held_pose.empty() && held_pose[at(p.images[at(j)])]) {
      std::fill_n(&p.cam_fixed[at(j) * at(cnp)], cc::kPoseParams, 1);
      ++p.held_poses;
    }
  eucsba::PointSet &s = p.points;
  s.ncameras = ms;
  s.xyz.reserve(at(n) * 3);
  std::vector<std::pair<int, const Point2D *>> track;
  for (int i = 0; i < n; ++i) {
    const Point3D &pt = model.points[at(i)];
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
      s.pairs.add(i, t.first);
      s.x.push_back(t.second->x);
      s.x.push_back(t.second->y);
    }
  }
  *out = std::move(p);
  return true;
}

void from_sba(const cc::CameraModel &sba_model, const ColmapProblem &problem, const double *p, int mcon, int ncon,
              Model *model) {
  const int m = static_cast<int>(problem.images.size());
  const int n = static_cast<int>(model->points.size());
  const int cnp = sba_model.cnp();
  std::unordered_map<std::uint32_t, Camera *> cameras;
  for (Camera &c : model->cameras) cameras.emplace(c.id, &c);
  std::unordered_map<std::uint32_t, int> camera_of;  // an image's sba camera
  std::vector<char> posed(model->images.size(), 0);  // the images whose pose is written
  for (int j = 0; j < m; ++j) {
    Image &im = model->images[at(problem.images[at(j)])];
    camera_of.emplace(im.id, j);
    if (j < mcon) continue;
    const char *fixed = &problem.cam_fixed[at(j) * at(cnp)];
    const cc::Camera c = sba_model.camera(j, p + at(j) * at(cnp));
    // A held pose is not written: the parametrization's round trip would move its last bits.
    if (!std::all_of(fixed, fixed + cc::kPoseParams, [](char f) { return f != 0; })) {
      im.q = {c.q.w, c.q.x, c.q.y, c.q.z};
      for (int k = 0; k < 3; ++k) im.t[at(k)] = c.t[at(k)];
      posed[at(problem.images[at(j)])] = 1;
    }
    const int group = problem.cam_group[at(j)];
    if (group >= 0 && group != j) continue;  // the group's first camera writes it
    Camera *cam = cameras.at(im.camera_id);
    for (std::size_t k = 0; k < cam->params.size(); ++k)
      if (!fixed[cc::kPoseParams + k]) cam->params[k] = c.params[k];
  }
  const double *points = p + at(m) * at(cnp);
  for (int i = ncon; i < n; ++i) {
    Point3D &pt = model->points[at(i)];
    const double *b = points + 3 * at(i);
    for (int k = 0; k < 3; ++k) pt.xyz[at(k)] = b[k];
    double sum = 0;
    for (const TrackElement &e : pt.track) {
      const int j = camera_of.at(e.image_id);
      const Point2D &obs = model->images[at(problem.images[at(j)])].points[e.point2d_idx];
      double x[2];
      sba_model.project(j, p + at(j) * at(cnp), b, x);
      sum += std::hypot(x[0] - obs.x, x[1] - obs.y);
    }
    pt.error = sum / static_cast<double>(pt.track.size());
  }
  // COLMAP 4 reads the poses from the frames (each of one image: to_sba).
  frames_from_poses(model, posed);
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
