// SPDX-License-Identifier: BSD-3-Clause
#include "formats/colmap_covariance.h"

#include <algorithm>
#include <cstddef>
#include <cstdio>
#include <numeric>

#include "cameras/colmap_camera.h"
#include "formats/colmap_problem.h"

namespace sbaformats::colmap {

namespace cc = sbacameras::colmap_camera;

namespace {

constexpr const char *kPoseCoords[] = {"rx", "ry", "rz", "tx", "ty", "tz"};
constexpr const char *kPointCoords[] = {"x", "y", "z"};

std::size_t at(int k) { return static_cast<std::size_t>(k); }

// The coordinates among `count` from parameter `first` of a camera that its flags leave free.
std::vector<int> free_coords(const char *fixed, int first, int count) {
  std::vector<int> coords;
  for (int k = 0; k < count; ++k)
    if (!fixed[first + k]) coords.push_back(k);
  return coords;
}

// The entries of the n x n row-major C over `coords`, its upper triangle mirrored: the
// library's blocks are symmetric only up to the rounding of the order of their sums.
std::vector<double> sub_block(const double *C, int n, const std::vector<int> &coords) {
  std::vector<double> out;
  for (int r : coords)
    for (int c : coords) out.push_back(C[at(std::min(r, c)) * at(n) + at(std::max(r, c))]);
  return out;
}

// The pose of parameters [first, first + 6) of a camera (a its parameters, cov its cnp x cnp
// block, fixed its flags) in COLMAP's tangent: T cov T^T with T = diag(d(delta)/dv, I).
CovarianceBlock pose_block(const double *a, const double *cov, const char *fixed, int cnp, int first) {
  double T[36] = {0};
  double J[9];
  cc::rotation_tangent_jacobian(a + first, J);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) T[r * 6 + c] = J[r * 3 + c];
    T[(r + 3) * 6 + r + 3] = 1.0;
  }
  double P[36] = {0};
  for (int r = 0; r < 6; ++r)
    for (int c = r; c < 6; ++c) {
      double s = 0;
      for (int k = 0; k < 6; ++k)
        for (int l = 0; l < 6; ++l) s += T[r * 6 + k] * cov[at(first + k) * at(cnp) + at(first + l)] * T[c * 6 + l];
      P[r * 6 + c] = s;
    }
  CovarianceBlock b;
  b.coords = free_coords(fixed, first, 6);
  b.cov = sub_block(P, 6, b.coords);
  return b;
}

void append_block(const char *kind, const CovarianceBlock &b, const char *const *names, std::string *text) {
  if (b.coords.empty()) return;
  char num[40];
  *text += kind;
  *text += ' ' + std::to_string(b.id) + (b.name.empty() ? "" : " " + b.name) + ' ';
  for (std::size_t k = 0; k < b.coords.size(); ++k)
    *text += (k ? "," : "") + (names ? std::string(names[b.coords[k]]) : std::to_string(b.coords[k]));
  for (double v : b.cov) {
    std::snprintf(num, sizeof num, " %.17g", v);
    *text += num;
  }
  *text += '\n';
}

}  // namespace

std::string covariance_text(const Covariances &c) {
  char head[160];
  std::snprintf(head, sizeof head, "SIGMA2 %.17g RANK %d NFREE %d\n", c.sigma2, c.rank, c.nfree);
  std::string text =
      "# Covariances of a refined COLMAP model for reprojection errors of unit variance (pixels^2;\n"
      "# times SIGMA2 for the errors the model has): poses over COLMAP's tangent [rotation,\n"
      "# translation], a record per line, held coordinates left out (docs/sbarefine.md)\n";
  text += head;
  for (const CovarianceBlock &b : c.images) append_block("IMAGE", b, kPoseCoords, &text);
  for (const CovarianceBlock &b : c.frames) append_block("FRAME", b, kPoseCoords, &text);
  for (const CovarianceBlock &b : c.sensors) append_block("SENSOR", b, kPoseCoords, &text);
  for (const CovarianceBlock &b : c.cameras) append_block("CAMERA", b, nullptr, &text);
  for (const CovarianceBlock &b : c.points) append_block("POINT", b, kPointCoords, &text);
  return text;
}

bool write_covariances(const std::string &path, const Covariances &c, std::string *error, OutputSet *outputs) {
  return write_whole_file(path, covariance_text(c), error, outputs);
}

bool Problem::covariance(const Model &model, const double *p, const sba_ext_options &ext, bool points,
                         Covariances *out) const {
  const int m = ncameras(), n = npoints();
  std::vector<int> cams(at(m)), pts(points ? at(n - held_points_) : 0);
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
    CovarianceBlock b;
    b.id = point_ids_[at(pts[q])];
    b.coords = {0, 1, 2};
    b.cov = sub_block(ptcov.data() + 9 * q, 3, b.coords);
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
      CovarianceBlock b = pose_block(a, cov, fixed, cnp_, 0);
      b.id = r.image;
      b.name = model.images[at(images_[at(j)])].name;
      if (!b.coords.empty()) out->images.push_back(std::move(b));
      continue;
    }
    // A frame's pose and a camera's pose in its rig are one each, whichever image holds them.
    if (std::find(frames_done.begin(), frames_done.end(), r.frame) == frames_done.end()) {
      frames_done.push_back(r.frame);
      CovarianceBlock b = pose_block(a, cov, fixed, cnp_, 0);
      b.id = r.frame;
      if (!b.coords.empty()) out->frames.push_back(std::move(b));
    }
    if (r.writes_params && !r.reference) {
      CovarianceBlock b = pose_block(a, cov, fixed, cnp_, cc::kPoseParams);
      b.id = r.camera;
      if (!b.coords.empty()) out->sensors.push_back(std::move(b));
    }
  }
}

void Problem::camera_covariances(const double *camcov, Covariances *out) const {
  const int first = rigged_ ? cc::kRigPoseParams : cc::kPoseParams;
  for (int j = mcon_; j < ncameras(); ++j) {
    const CameraIds &r = ids_[at(j)];
    if (!r.writes_params) continue;
    const int count = static_cast<int>(
        rigged_ ? rig_model_->input_image(j).params.size() : image_model_->input_camera(j).params.size());
    CovarianceBlock b;
    b.id = r.camera;
    b.coords = free_coords(&cam_fixed_[at(j) * at(cnp_)], first, count);
    b.cov = sub_block(camcov + at(j) * at(cnp_) * at(cnp_) + first * (cnp_ + 1), cnp_, b.coords);
    if (!b.coords.empty()) out->cameras.push_back(std::move(b));
  }
}

}  // namespace sbaformats::colmap
