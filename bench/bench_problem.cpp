// SPDX-License-Identifier: BSD-3-Clause
#include "bench_problem.h"

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <string>
#include <utility>
#include <vector>

#include "formats/bal_io.h"
#include "formats/eucsba_io.h"
#include "generator/sbagen.h"

namespace eucsba = sbaformats::eucsba;
namespace bal = sbaformats::bal;
namespace euclidean = sbacameras::euclidean;
namespace bal_camera = sbacameras::bal;

namespace sbabench {

void *Problem::adata() const {
  if (model_kind == ModelKind::Bal) return const_cast<bal_camera::CallbackData *>(&bal_data);
  return euclidean::as_adata(*euc);
}

Problem::ExpertFn Problem::func() const {
  if (model_kind == ModelKind::Bal) return bal_camera::motstr_func;
  return euclidean::expert_callbacks(euc->kind(), euclidean::Refinement::MotionStructure).func;
}

Problem::ExpertFn Problem::fjac() const {
  if (model_kind == ModelKind::Bal) return bal_camera::motstr_fjac;
  return euclidean::expert_callbacks(euc->kind(), euclidean::Refinement::MotionStructure).fjac;
}

euclidean::MotStrCallbacks Problem::simple() const {
  if (model_kind == ModelKind::Bal) return {bal_camera::motstr_proj, bal_camera::motstr_projac};
  return euclidean::motstr_callbacks(euc->kind());
}

std::vector<int> Problem::held_camera_params() const {
  std::vector<int> held;
  if (model_kind != ModelKind::Eucsba || euc->kind() == euclidean::CameraKind::FixedIntrinsics) return held;
  // (fu u0 v0 ar s [kc0..kc4] ...): the trailing nccalib intrinsics and ncdist distortion terms.
  for (int c = euclidean::kIntrinsicParams - euc->nccalib(); c < euclidean::kIntrinsicParams; ++c) held.push_back(c);
  if (euc->kind() == euclidean::CameraKind::VaryingIntrinsicsDistortion)
    for (int c = euclidean::kDistortionParams - euc->ncdist(); c < euclidean::kDistortionParams; ++c)
      held.push_back(euclidean::kIntrinsicParams + c);
  return held;
}

long long Problem::camera_pairs() const {
  // Points of each camera, then for each camera the distinct cameras >= it among the
  // tracks of its points (stamped, so no set is needed).
  std::vector<std::size_t> begin(static_cast<std::size_t>(m) + 1, 0);
  for (int j : obs_camera) ++begin[static_cast<std::size_t>(j) + 1];
  for (int j = 0; j < m; ++j) begin[j + 1] += begin[j];
  std::vector<int> pts(obs_camera.size());
  std::vector<std::size_t> fill(begin.begin(), begin.end() - 1);
  for (std::size_t k = 0; k < obs_camera.size(); ++k) pts[fill[obs_camera[k]]++] = obs_point[k];
  std::vector<std::size_t> track(static_cast<std::size_t>(n) + 1, 0);  // observations by point
  for (int i : obs_point) ++track[static_cast<std::size_t>(i) + 1];
  for (int i = 0; i < n; ++i) track[i + 1] += track[i];
  std::vector<int> stamp(static_cast<std::size_t>(m), -1);
  long long pairs = 0;
  for (int j = 0; j < m; ++j)
    for (std::size_t e = begin[j]; e < begin[j + 1]; ++e) {
      const int i = pts[e];
      for (std::size_t k = track[i]; k < track[i + 1]; ++k) {
        const int j2 = obs_camera[k];
        if (j2 >= j && stamp[j2] != j) {
          stamp[j2] = j;
          ++pairs;
        }
      }
    }
  return pairs;
}

void index_observations(Problem *p) {
  p->obs_camera.clear();
  p->obs_point.clear();
  p->obs_camera.reserve(p->nobs());
  p->obs_point.reserve(p->nobs());
  for (int i = 0; i < p->n; ++i) {
    const char *row = p->vmask.data() + static_cast<std::size_t>(i) * p->m;
    for (int j = 0; j < p->m; ++j)
      if (row[j]) {
        p->obs_camera.push_back(j);
        p->obs_point.push_back(i);
      }
  }
}

namespace {

std::string base_name(const std::string &path) {
  const std::size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

void fill_eucsba(euclidean::CameraKind kind, const std::vector<euclidean::Camera> &cameras, eucsba::PointSet &pts,
                 Problem *out) {
  out->model_kind = ModelKind::Eucsba;
  out->euc = std::make_unique<euclidean::CameraModel>(kind, cameras, pts.xyz);
  out->n = pts.npoints();
  out->m = pts.ncameras;
  out->cnp = out->euc->cnp();
  out->vmask = std::move(pts.vmask);
  out->x = std::move(pts.x);
  out->p0 = out->euc->initial_camera_params();
  out->p0.insert(out->p0.end(), out->euc->initial_points().begin(), out->euc->initial_points().end());
  index_observations(out);
}

}  // namespace

bool load_eucsba(const std::string &cams, const std::string &pts, const std::string &calib, Problem *out,
                 std::string *error) {
  eucsba::Problem problem;
  if (!eucsba::load_problem(cams, pts, calib, &problem, error)) return false;
  if (problem.points.has_covariances()) {
    *error = pts + ": measurement covariances are not supported by the benchmark";
    return false;
  }
  if (out->name.empty()) {
    out->name = base_name(cams);
    const std::size_t dot = out->name.rfind(".txt");
    if (dot != std::string::npos) out->name.erase(dot);
  }
  out->description = "eucsbademo " + base_name(cams) + " " + base_name(pts) + (calib.empty() ? "" : " " + base_name(calib));
  fill_eucsba(problem.kind, problem.cameras, problem.points, out);
  return true;
}

bool load_bal(const std::string &path, Problem *out, std::string *error) {
  bal::Problem problem;
  bal::SbaLayout s;
  if (!bal::read_problem(path, &problem, error) || !bal::to_sba(problem, path, &s, error)) return false;
  if (out->name.empty()) {
    out->name = base_name(path);
    for (const char *ext : {".bz2", ".txt"}) {
      const std::size_t dot = out->name.rfind(ext);
      if (dot != std::string::npos && dot + std::string(ext).size() == out->name.size()) out->name.erase(dot);
    }
  }
  out->description = "BAL " + base_name(path);
  out->model_kind = ModelKind::Bal;
  out->n = s.n;
  out->m = s.m;
  out->cnp = bal_camera::kCameraParams;
  out->vmask = s.vis.vmask(s.n, s.m);
  out->x = std::move(s.x);
  out->p0 = std::move(s.p);
  out->bal_data.ncameras = s.m;
  index_observations(out);
  return true;
}

namespace {

bool parse_long(const std::string &v, long long lo, long long hi, long long *out) {
  errno = 0;
  char *end = nullptr;
  const long long r = std::strtoll(v.c_str(), &end, 10);
  if (v.empty() || errno != 0 || *end != '\0' || r < lo || r > hi) return false;
  *out = r;
  return true;
}

}  // namespace

bool generate(const std::string &spec, Problem *out, std::string *error) {
  sbagen::Options o;
  o.dense_vmask_limit = 0;  // built below from the tracks
  std::size_t start = 0;
  while (start < spec.size()) {
    std::size_t comma = spec.find(',', start);
    if (comma == std::string::npos) comma = spec.size();
    const std::string item = spec.substr(start, comma - start);
    start = comma + 1;
    const std::size_t eq = item.find('=');
    if (eq == std::string::npos) {
      *error = "--gen: expected key=value, got '" + item + "'";
      return false;
    }
    const std::string key = item.substr(0, eq), value = item.substr(eq + 1);
    long long v = 0;
    bool ok = true;
    if (key == "cameras") {
      ok = parse_long(value, 2, 1000000, &v);
      o.cameras = static_cast<int>(v);
    } else if (key == "points") {
      ok = parse_long(value, 1, 100000000, &v);
      o.points = static_cast<int>(v);
    } else if (key == "track") {
      const std::size_t dots = value.find("..");
      long long lo = 0, hi = 0;
      if (dots == std::string::npos) {
        ok = parse_long(value, 2, 100000, &lo);
        hi = lo;
      } else {
        ok = parse_long(value.substr(0, dots), 2, 100000, &lo) &&
             parse_long(value.substr(dots + 2), 2, 100000, &hi);
      }
      o.track_min = static_cast<int>(lo);
      o.track_max = static_cast<int>(hi);
    } else if (key == "trajectory") {
      ok = sbagen::trajectory_from_name(value, &o.trajectory);
    } else if (key == "kind") {
      if (value == "fixed") o.kind = euclidean::CameraKind::FixedIntrinsics;
      else if (value == "varK") o.kind = euclidean::CameraKind::VaryingIntrinsics;
      else if (value == "varKD") o.kind = euclidean::CameraKind::VaryingIntrinsicsDistortion;
      else ok = false;
    } else if (key == "noise") {
      char *end = nullptr;
      o.noise = std::strtod(value.c_str(), &end);
      ok = !value.empty() && *end == '\0' && o.noise >= 0;
    } else if (key == "seed") {
      ok = parse_long(value, 0, (1LL << 62), &v);
      o.seed = static_cast<std::uint64_t>(v);
    } else {
      *error = "--gen: unknown key '" + key + "' (cameras, points, track, trajectory, kind, noise, seed)";
      return false;
    }
    if (!ok) {
      *error = "--gen: bad value '" + value + "' for " + key;
      return false;
    }
  }
  if (!o.IsValid(error)) {
    *error = "--gen: " + *error;
    return false;
  }
  sbagen::Scene scene;
  if (!sbagen::generate(o, &scene, error)) {
    *error = "--gen: " + *error;
    return false;
  }
  if (out->name.empty())
    out->name = std::string("gen-") + sbagen::trajectory_name(o.trajectory) + "-" + std::to_string(o.cameras) +
                "c-" + std::to_string(o.points) + "p-t" + std::to_string(o.track_min) + "-" +
                std::to_string(o.track_max);
  out->description = "sbagen " + spec;
  // No dense vmask: the solvers get the tracks as (point, camera) pairs (sba's _vis entry
  // point), so the n*m chars of a long sequence do not count against it.
  eucsba::PointSet pts = std::move(scene.measurements);
  // The tracks give the observation index directly (no n*m scan).
  std::vector<euclidean::Camera> cameras = std::move(scene.initial_cameras);
  const euclidean::CameraKind kind = scene.kind;
  std::vector<int> cams = std::move(scene.track_cameras);
  std::vector<std::size_t> begin = std::move(scene.track_begin);
  scene = sbagen::Scene();  // the truth is not needed any more
  out->model_kind = ModelKind::Eucsba;
  out->euc = std::make_unique<euclidean::CameraModel>(kind, cameras, pts.xyz);
  out->n = pts.npoints();
  out->m = pts.ncameras;
  out->cnp = out->euc->cnp();
  out->x = std::move(pts.x);
  out->p0 = out->euc->initial_camera_params();
  out->p0.insert(out->p0.end(), out->euc->initial_points().begin(), out->euc->initial_points().end());
  out->obs_camera = std::move(cams);
  out->obs_point.resize(out->obs_camera.size());
  for (int i = 0; i < out->n; ++i)
    for (std::size_t k = begin[i]; k < begin[i + 1]; ++k) out->obs_point[k] = i;
  return true;
}

}  // namespace sbabench
