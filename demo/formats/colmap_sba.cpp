// SPDX-License-Identifier: BSD-3-Clause
#include "formats/colmap_sba.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstddef>
#include <unordered_map>
#include <utility>

namespace sbaformats::colmap {

namespace {

bool fail(std::string *error, const std::string &msg) {
  if (error) *error = msg;
  return false;
}

// Distortion terms of each model: a leading run of Bouguet's kc.
int distortion_terms(int model) {
  switch (model) {
    case kSimpleRadial: return 1;
    case kRadial: return 2;
    case kOpenCV: return 4;
    default: return 0;
  }
}

sbacameras::euclidean::Camera to_camera(const Camera &c, const Image &im) {
  sbacameras::euclidean::Camera out;
  const std::vector<double> &p = c.params;
  switch (c.model) {
    case kSimplePinhole:
    case kSimpleRadial:
    case kRadial:
      out.k.fu = p[0];
      out.k.u0 = p[1];
      out.k.v0 = p[2];
      for (int k = 0; k < distortion_terms(c.model); ++k) out.kc[k] = p[3 + k];
      break;
    default:  // PINHOLE, OPENCV
      out.k.fu = p[0];
      out.k.ar = p[1] / p[0];
      out.k.u0 = p[2];
      out.k.v0 = p[3];
      for (int k = 0; k < distortion_terms(c.model); ++k) out.kc[k] = p[4 + k];
      break;
  }
  out.q = {im.q[0], im.q[1], im.q[2], im.q[3]};
  for (int k = 0; k < 3; ++k) out.t[k] = im.t[k];
  return out;
}

// The refined intrinsics (the first free_intr of fu u0 v0, the first free_dist of kc) into
// COLMAP's parameters.
void set_intrinsics(const sbacameras::euclidean::Camera &c, int free_intr, int free_dist, Camera *out) {
  std::vector<double> &p = out->params;
  const bool two_focals = out->model == kPinhole || out->model == kOpenCV;
  const int pp = two_focals ? 2 : 1;  // where cx is
  if (free_intr >= 1) {
    p[0] = c.k.fu;
    if (two_focals) p[1] = c.k.fu * c.k.ar;
  }
  if (free_intr >= 3) {
    p[static_cast<std::size_t>(pp)] = c.k.u0;
    p[static_cast<std::size_t>(pp) + 1] = c.k.v0;
  }
  const int nd = std::min(free_dist, distortion_terms(out->model));
  for (int k = 0; k < nd; ++k) p[static_cast<std::size_t>(pp + 2 + k)] = c.kc[k];
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
  if (r.principal && !r.focal) return "the principal point is refined only with the focal length (focal,principal)";
  *out = r;
  return {};
}

bool to_sba(const Model &model, const RefineIntrinsics &refine, const std::string &name, SbaProblem *out,
            std::string *error) {
  const std::string where = name + ": ";
  std::unordered_map<std::uint32_t, const Camera *> cameras;
  for (const Camera &c : model.cameras) cameras.emplace(c.id, &c);
  std::unordered_map<std::uint32_t, int> image_index, users;
  const int m = static_cast<int>(model.images.size());
  const int n = static_cast<int>(model.points.size());
  if (m == 0 || n == 0) return fail(error, where + "the model has no images or no points");
  for (int j = 0; j < m; ++j) {
    const Image &im = model.images[static_cast<std::size_t>(j)];
    image_index.emplace(im.id, j);
    ++users[im.camera_id];
  }
  // An image is a camera of the problem when it sees a point (every point is seen: check_model).
  std::vector<int> camera_of(static_cast<std::size_t>(m), -1);
  for (const Point3D &pt : model.points)
    for (const TrackElement &e : pt.track) camera_of[static_cast<std::size_t>(image_index.at(e.image_id))] = 0;
  int dist = 4;
  for (int j = 0; j < m; ++j)
    if (camera_of[static_cast<std::size_t>(j)] == 0)
      dist = std::min(dist, distortion_terms(cameras.at(model.images[static_cast<std::size_t>(j)].camera_id)->model));
  SbaProblem p;
  p.nccalib = refine.focal ? (refine.principal ? 2 : 4) : 5;
  p.ncdist = refine.distortion ? sbacameras::euclidean::kDistortionParams - dist : sbacameras::euclidean::kDistortionParams;
  const bool intrinsics = p.nccalib < sbacameras::euclidean::kIntrinsicParams || p.ncdist < sbacameras::euclidean::kDistortionParams;
  for (int j = 0; j < m; ++j) {
    if (camera_of[static_cast<std::size_t>(j)] < 0) continue;
    const Image &im = model.images[static_cast<std::size_t>(j)];
    if (intrinsics && users[im.camera_id] > 1)
      return fail(error, where + "camera " + std::to_string(im.camera_id) + " is shared by " +
                             std::to_string(users[im.camera_id]) +
                             " images: sba refines each image's intrinsics on their own; hold them "
                             "(--intrinsics none) or give each image a camera of its own");
    camera_of[static_cast<std::size_t>(j)] = static_cast<int>(p.cameras.size());
    p.cameras.push_back(to_camera(*cameras.at(im.camera_id), im));
    p.images.push_back(j);
  }
  eucsba::PointSet &s = p.points;
  s.ncameras = static_cast<int>(p.cameras.size());
  s.xyz.reserve(static_cast<std::size_t>(n) * 3);
  std::vector<std::pair<int, const Point2D *>> track;
  for (int i = 0; i < n; ++i) {
    const Point3D &pt = model.points[static_cast<std::size_t>(i)];
    s.xyz.insert(s.xyz.end(), pt.xyz.begin(), pt.xyz.end());
    track.clear();
    for (const TrackElement &e : pt.track) {
      const int j = image_index.at(e.image_id);
      track.push_back({camera_of[static_cast<std::size_t>(j)],
                       &model.images[static_cast<std::size_t>(j)].points[e.point2d_idx]});
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

void from_sba(const sbacameras::euclidean::CameraModel &sba_model, const SbaProblem &problem, const double *p, int mcon, int ncon,
              Model *model) {
  const int m = static_cast<int>(problem.images.size());
  const int n = static_cast<int>(model->points.size());
  const int cnp = sba_model.cnp();
  std::unordered_map<std::uint32_t, Camera *> cameras;
  for (Camera &c : model->cameras) cameras.emplace(c.id, &c);
  std::unordered_map<std::uint32_t, int> camera_of;  // an image's sba camera
  for (int j = 0; j < m; ++j) {
    Image &im = model->images[static_cast<std::size_t>(problem.images[static_cast<std::size_t>(j)])];
    camera_of.emplace(im.id, j);
    if (j < mcon) continue;
    const sbacameras::euclidean::Camera c = sba_model.camera(j, p + static_cast<std::size_t>(j) * cnp);
    im.q = {c.q.w, c.q.x, c.q.y, c.q.z};
    for (int k = 0; k < 3; ++k) im.t[k] = c.t[k];
    set_intrinsics(c, sbacameras::euclidean::kIntrinsicParams - problem.nccalib, sbacameras::euclidean::kDistortionParams - problem.ncdist,
                   cameras.at(im.camera_id));
  }
  const double *points = p + static_cast<std::size_t>(m) * cnp;
  for (int i = ncon; i < n; ++i) {
    Point3D &pt = model->points[static_cast<std::size_t>(i)];
    const double *b = points + 3 * static_cast<std::size_t>(i);
    for (int k = 0; k < 3; ++k) pt.xyz[k] = b[k];
    double sum = 0;
    for (const TrackElement &e : pt.track) {
      const int j = camera_of.at(e.image_id);
      const Point2D &obs =
          model->images[static_cast<std::size_t>(problem.images[static_cast<std::size_t>(j)])].points[e.point2d_idx];
      double x[2];
      sba_model.project(j, p + static_cast<std::size_t>(j) * cnp, b, x);
      sum += std::hypot(x[0] - obs.x, x[1] - obs.y);
    }
    pt.error = sum / static_cast<double>(pt.track.size());
  }
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
