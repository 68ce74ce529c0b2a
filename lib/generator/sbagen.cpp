// SPDX-License-Identifier: BSD-3-Clause
// sbagen: see sbagen.h.
#include "sbagen.h"

#include <algorithm>
#include <array>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <utility>

namespace eucsba = sbaformats::eucsba;
namespace euclidean = sbacameras::euclidean;

namespace sbagen {

namespace {
constexpr double kPi = 3.14159265358979323846;
}  // namespace

using euclidean::Camera;
using euclidean::CameraKind;
using euclidean::Quaternion;

// ---- Random ----

std::uint64_t Random::below(std::uint64_t n) {
  // Values under `threshold` belong to an incomplete block of n and are drawn again, so every
  // residue is equally likely.
  const std::uint64_t threshold = (0 - n) % n;
  for (;;) {
    const std::uint64_t r = bits();
    if (r >= threshold) return r % n;
  }
}

double Random::normal() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  const double u1 = 1.0 - uniform();  // (0, 1]: the logarithm stays finite
  const double u2 = uniform();
  const double r = std::sqrt(-2.0 * std::log(u1));
  const double angle = 2.0 * kPi * u2;
  spare_ = r * std::sin(angle);
  has_spare_ = true;
  return r * std::cos(angle);
}

// ---- names ----

const char *trajectory_name(Trajectory t) {
  switch (t) {
    case Trajectory::Orbit: return "orbit";
    case Trajectory::Path: return "path";
    case Trajectory::Photo: return "photo";
  }
  return "?";
}

bool trajectory_from_name(const std::string &name, Trajectory *t) {
  for (Trajectory c : {Trajectory::Orbit, Trajectory::Path, Trajectory::Photo})
    if (name == trajectory_name(c)) {
      *t = c;
      return true;
    }
  return false;
}

const char *camera_kind_name(CameraKind kind) {
  switch (kind) {
    case CameraKind::FixedIntrinsics: return "fixed";
    case CameraKind::VaryingIntrinsics: return "varK";
    case CameraKind::VaryingIntrinsicsDistortion: return "varKD";
  }
  return "?";
}

// ---- options ----

namespace {

// sba counts projections (and their 2 or 4 values) in int.
constexpr long long kMaxProjections = INT_MAX / 4;

bool fail(std::string *error, std::string message) {
  if (error) *error = std::move(message);
  return false;
}

bool finite_in(double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; }

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

}  // namespace

bool Options::IsValid(std::string *error) const {
  if (cameras < 2) return fail(error, "cameras must be at least 2 (got " + std::to_string(cameras) + ")");
  if (points < 1) return fail(error, "points must be at least 1 (got " + std::to_string(points) + ")");
  if (track_min < 2) return fail(error, "track_min must be at least 2 (got " + std::to_string(track_min) + ")");
  if (track_max < track_min)
    return fail(error, "track_max (" + std::to_string(track_max) + ") is below track_min (" +
                           std::to_string(track_min) + ")");
  if (track_min > cameras)
    return fail(error, "track_min (" + std::to_string(track_min) + ") exceeds cameras (" +
                           std::to_string(cameras) + ")");
  if (static_cast<long long>(points) * std::min(track_max, cameras) > kMaxProjections)
    return fail(error, "too many projections for sba's int counts (points * track_max > " +
                           std::to_string(kMaxProjections) + ")");
  if (image_width < 16 || image_height < 16 || image_width > 100000 || image_height > 100000)
    return fail(error, "image size must be between 16 and 100000 pixels a side (got " +
                           std::to_string(image_width) + "x" + std::to_string(image_height) + ")");
  if (!finite_in(focal, 1.0, 1e6)) return fail(error, "focal must be between 1 and 1e6 pixels (got " + num(focal) + ")");
  if (!finite_in(intrinsics_spread, 0, 0.2))
    return fail(error, "intrinsics_spread must be between 0 and 0.2 (got " + num(intrinsics_spread) + ")");
  if (!finite_in(distortion, 0, 0.5)) return fail(error, "distortion must be between 0 and 0.5 (got " + num(distortion) + ")");
  if (!(std::isfinite(orbit_arc_deg) && orbit_arc_deg > 0 && orbit_arc_deg <= 360))
    return fail(error, "orbit_arc_deg must be in (0, 360] (got " + num(orbit_arc_deg) + ")");
  if (!finite_in(path_yaw_deg, -90, 90)) return fail(error, "path_yaw_deg must be between -90 and 90 (got " + num(path_yaw_deg) + ")");
  if (!finite_in(path_turn_deg, 0, 45)) return fail(error, "path_turn_deg must be between 0 and 45 (got " + num(path_turn_deg) + ")");
  const double max_noise = std::min(image_width, image_height) / 40.0;
  if (!finite_in(noise, 0, max_noise))
    return fail(error, "noise must be between 0 and " + num(max_noise) + " pixels for this image (got " + num(noise) + ")");
  if (covariances && noise <= 0) return fail(error, "covariances need a noise sigma above 0");
  if (!finite_in(outliers, 0, 1)) return fail(error, "outliers must be a fraction between 0 and 1 (got " + num(outliers) + ")");
  if (!finite_in(perturb_rotation, 0, 0.5))
    return fail(error, "perturb_rotation must be between 0 and 0.5 radians (got " + num(perturb_rotation) + ")");
  if (!finite_in(perturb_translation, 0, 10))
    return fail(error, "perturb_translation must be between 0 and 10 (got " + num(perturb_translation) + ")");
  if (!finite_in(perturb_points, 0, 10)) return fail(error, "perturb_points must be between 0 and 10 (got " + num(perturb_points) + ")");
  if (!finite_in(perturb_intrinsics, 0, 0.2))
    return fail(error, "perturb_intrinsics must be between 0 and 0.2 (got " + num(perturb_intrinsics) + ")");
  return true;
}

std::size_t Scene::noutliers() const {
  return static_cast<std::size_t>(std::count_if(outlier.begin(), outlier.end(), [](char c) { return c != 0; }));
}

// ---- geometry ----

namespace {

struct Vec3 {
  double x = 0, y = 0, z = 0;
};
Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3 operator*(double s, Vec3 a) { return {s * a.x, s * a.y, s * a.z}; }
double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
Vec3 cross(Vec3 a, Vec3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
Vec3 unit(Vec3 a) { return (1.0 / std::sqrt(dot(a, a))) * a; }

// A camera at centre C looking along `forward`, image x to the right of it with the world's
// +Y up (image y down), rolled by `roll` radians about the optical axis. Sets q and t.
void look_along(Vec3 C, Vec3 forward, double roll, Camera *cam) {
  const Vec3 up{0, 1, 0};
  const Vec3 z = unit(forward);
  const Vec3 x0 = unit(cross(z, up));
  const Vec3 y0 = cross(z, x0);
  const double c = std::cos(roll), s = std::sin(roll);
  const Vec3 x = c * x0 + s * y0;
  const Vec3 y = (-s) * x0 + c * y0;
  const double R[9] = {x.x, x.y, x.z, y.x, y.y, y.z, z.x, z.y, z.z};
  cam->q = euclidean::quaternion_of(R);
  // t = -R C, from the rotation the quaternion actually encodes.
  double Rq[9];
  euclidean::rotation_matrix(cam->q, Rq);
  for (int r = 0; r < 3; ++r) cam->t[r] = -(Rq[3 * r] * C.x + Rq[3 * r + 1] * C.y + Rq[3 * r + 2] * C.z);
}

// The small rotation exp(w/2) as a unit quaternion.
Quaternion small_rotation(double wx, double wy, double wz) {
  const double angle = std::sqrt(wx * wx + wy * wy + wz * wz);
  if (angle == 0) return {};
  const double s = std::sin(0.5 * angle) / angle;
  return {std::cos(0.5 * angle), s * wx, s * wy, s * wz};
}

// Which projections count as visible: in front of the camera, within a radius where the lens
// distortion is still monotonic (so no point from outside the field of view folds back into
// the image), and inside the image with a margin. Projection itself is eucsbademo's camera
// model (cameras/euclidean.h).
class Visibility {
 public:
  Visibility(CameraKind kind, const std::vector<Camera> &cameras, int width, int height, double margin,
             double min_depth)
      : model_(kind, cameras, {}),
        R_(cameras.size() * 9),
        r2max_(cameras.size()),
        umin_(margin),
        vmin_(margin),
        umax_(width - 1 - margin),
        vmax_(height - 1 - margin),
        min_depth_(min_depth) {
    for (std::size_t j = 0; j < cameras.size(); ++j) {
      euclidean::rotation_matrix(model_.input_camera(static_cast<int>(j)).q, &R_[9 * j]);
      r2max_[j] = monotonic_radius2(kind == CameraKind::VaryingIntrinsicsDistortion ? cameras[j].kc.data() : nullptr);
    }
  }

  // True if camera j sees X; its projection in x.
  bool sees(int j, const double X[3], double x[2]) const {
    const double *R = &R_[9 * static_cast<std::size_t>(j)];
    const Camera &c = model_.input_camera(j);
    const double Z = R[6] * X[0] + R[7] * X[1] + R[8] * X[2] + c.t[2];
    if (!(Z > min_depth_)) return false;
    const double xn = (R[0] * X[0] + R[1] * X[1] + R[2] * X[2] + c.t[0]) / Z;
    const double yn = (R[3] * X[0] + R[4] * X[1] + R[5] * X[2] + c.t[1]) / Z;
    if (xn * xn + yn * yn > r2max_[j]) return false;
    model_.project(j, model_.initial_camera(j), X, x);
    return x[0] >= umin_ && x[0] <= umax_ && x[1] >= vmin_ && x[1] <= vmax_;
  }

 private:
  // The largest r^2 (capped at 4, i.e. 63 degrees off axis) up to which the radial factor
  // d(r (1 + kc0 r^2 + kc1 r^4 + kc4 r^6))/dr stays above 1/2.
  static double monotonic_radius2(const double *kc) {
    constexpr double kCap = 4.0;
    if (!kc) return kCap;
    constexpr int kSteps = 4000;
    for (int s = 1; s <= kSteps; ++s) {
      const double r2 = kCap * s / kSteps;
      if (1 + 3 * kc[0] * r2 + 5 * kc[1] * r2 * r2 + 7 * kc[4] * r2 * r2 * r2 < 0.5) return kCap * (s - 1) / kSteps;
    }
    return kCap;
  }

  euclidean::CameraModel model_;
  std::vector<double> R_;
  std::vector<double> r2max_;
  double umin_, vmin_, umax_, vmax_;
  double min_depth_;
};

// ---- true cameras ----

struct Lens {
  euclidean::Intrinsics k;
  std::array<double, euclidean::kDistortionParams> kc{};
};

// The shared lens the cameras are variations of.
Lens base_lens(const Options &o, Random &rng) {
  Lens lens;
  lens.k.fu = o.focal;
  lens.k.u0 = 0.5 * (o.image_width - 1) + rng.uniform(-0.01, 0.01) * o.image_width;
  lens.k.v0 = 0.5 * (o.image_height - 1) + rng.uniform(-0.01, 0.01) * o.image_height;
  lens.k.ar = 1;
  lens.k.s = 0;
  if (o.kind == CameraKind::VaryingIntrinsicsDistortion) {
    lens.kc[0] = rng.uniform(-o.distortion, o.distortion);
    lens.kc[1] = rng.uniform(-0.25 * o.distortion, 0.25 * o.distortion);
  }
  return lens;
}

// Camera j's own lens.
void camera_lens(const Options &o, const Lens &base, Random &rng, Camera *cam) {
  cam->k = base.k;
  if (o.kind == CameraKind::FixedIntrinsics) return;
  const double spread = o.intrinsics_spread;
  cam->k.fu = base.k.fu * (1 + spread * rng.normal());
  cam->k.u0 = base.k.u0 + spread * 0.25 * o.image_width * rng.normal();
  cam->k.v0 = base.k.v0 + spread * 0.25 * o.image_height * rng.normal();
  if (o.kind != CameraKind::VaryingIntrinsicsDistortion) return;
  const double d = o.distortion;
  cam->kc[0] = base.kc[0] + 0.05 * d * rng.normal();
  cam->kc[1] = base.kc[1] + 0.0125 * d * rng.normal();
  cam->kc[2] = rng.uniform(-0.01 * d, 0.01 * d);
  cam->kc[3] = rng.uniform(-0.01 * d, 0.01 * d);
  cam->kc[4] = 0;
}

// Half the narrower field of view of the base lens, as tan(angle).
double half_fov_tan(const Options &o) {
  return 0.5 * std::min(o.image_width, o.image_height) / o.focal;
}

// Orbit: cameras around the unit ball, at the distance where the ball fills the narrower
// field of view less a 15% margin, on an arc of the horizontal circle with the elevation
// weaving +-0.25 rad, each looking near the centre with a small roll.
double orbit_distance(const Options &o) {
  const double half_angle = std::atan(half_fov_tan(o));
  return 1.15 / std::sin(half_angle);
}

void orbit_cameras(const Options &o, Random &rng, std::vector<Camera> *cams) {
  const int m = o.cameras;
  const double D = orbit_distance(o);
  const double arc = o.orbit_arc_deg * kPi / 180.0;
  const bool full = o.orbit_arc_deg >= 360.0;
  const double spacing = full ? arc / m : arc / (m - 1);
  for (int j = 0; j < m; ++j) {
    Camera &c = (*cams)[j];
    const double theta = (full ? arc * j / m : -0.5 * arc + spacing * j) + 0.1 * spacing * rng.normal();
    const double phi = 0.25 * std::sin(3.0 * 2.0 * kPi * j / m) + 0.03 * rng.normal();
    const double dist = D * (1 + 0.03 * rng.normal());
    const Vec3 C = dist * Vec3{std::cos(phi) * std::sin(theta), std::sin(phi), std::cos(phi) * std::cos(theta)};
    const Vec3 target{0.05 * rng.normal(), 0.05 * rng.normal(), 0.05 * rng.normal()};
    look_along(C, target - C, 0.05 * rng.normal(), &c);
  }
}

// Photo: people photograph a landmark (the unit ball) from a few popular spots, standing at
// 1 to 4 times the distance where it fills the view, on the front 120 degrees of it and a
// little above; about sqrt(m)/2 spots, each camera near one of them (jitter of a tenth of the
// nearest distance), looking near the centre. Every camera then sees most of the points.
constexpr double kPhotoArc = 120.0 * kPi / 180.0;

void photo_cameras(const Options &o, Random &rng, std::vector<Camera> *cams) {
  const int m = o.cameras;
  const double D = orbit_distance(o);
  const int spots = std::max(1, static_cast<int>(std::lround(0.5 * std::sqrt(static_cast<double>(m)))));
  std::vector<Vec3> spot(spots);
  for (Vec3 &c : spot) {
    const double theta = rng.uniform(-0.5 * kPhotoArc, 0.5 * kPhotoArc);
    const double phi = rng.uniform(0.0, 0.3);
    const double dist = D * rng.uniform(1.1, 4.0);
    c = dist * Vec3{std::cos(phi) * std::sin(theta), std::sin(phi), std::cos(phi) * std::cos(theta)};
  }
  for (int j = 0; j < m; ++j) {
    const Vec3 &s = spot[rng.below(static_cast<std::uint64_t>(spots))];
    const Vec3 C = s + 0.1 * D * Vec3{rng.normal(), rng.normal(), rng.normal()};
    const Vec3 target{0.1 * rng.normal(), 0.1 * rng.normal(), 0.1 * rng.normal()};
    look_along(C, target - C, 0.05 * rng.normal(), &(*cams)[j]);
  }
}

// Photo: track lengths from a Pareto tail with this exponent, x_min = track_min: a mean of
// 4 track_min untruncated, with the few very long tracks of the points everyone photographs.
constexpr double kPhotoTrackTail = 4.0 / 3.0;

int photo_track_length(const Options &o, Random &rng) {
  const double u = 1.0 - rng.uniform();  // (0, 1]
  const double L = o.track_min * std::pow(u, -1.0 / kPhotoTrackTail);
  const int hi = std::min(o.track_max, o.cameras);
  return L >= hi ? hi : std::max(o.track_min, static_cast<int>(L));
}

// Path: one camera per unit step along a road in the X-Z plane whose heading weaves
// +-path_turn_deg with a period of 40 steps, the height bobbing by 0.05; each camera looks
// along the heading turned by path_yaw_deg, with jitter of 0.01 rad in yaw, pitch and roll.
constexpr double kPathPeriod = 40.0;
constexpr double kPathDepthMin = 2.0, kPathDepthMax = 12.0;

void path_cameras(const Options &o, Random &rng, std::vector<Camera> *cams) {
  const double turn = o.path_turn_deg * kPi / 180.0;
  const double yaw = o.path_yaw_deg * kPi / 180.0;
  auto heading = [&](double s) { return turn * std::sin(2.0 * kPi * s / kPathPeriod); };
  Vec3 C{0, 0, 0};
  for (int j = 0; j < o.cameras; ++j) {
    if (j > 0) {
      const double h = heading(j - 0.5);
      C.x += std::sin(h);
      C.z += std::cos(h);
    }
    const Vec3 centre{C.x, 0.05 * std::sin(2.0 * kPi * j / 23.0), C.z};
    const double look = heading(j) + yaw + 0.01 * rng.normal();
    const double pitch = 0.01 * rng.normal();
    const Vec3 forward{std::sin(look) * std::cos(pitch), std::sin(pitch), std::cos(look) * std::cos(pitch)};
    look_along(centre, forward, 0.01 * rng.normal(), &(*cams)[j]);
  }
}

// ---- points and tracks ----

// Collects the tracks while they are built.
struct TrackBuilder {
  std::vector<int> cams;      // the track being built
  std::vector<double> xs;     // its projections, 2 per camera
  std::vector<int> order;     // scratch for sorting

  void clear() {
    cams.clear();
    xs.clear();
  }
  void add(int j, const double x[2]) {
    cams.push_back(j);
    xs.push_back(x[0]);
    xs.push_back(x[1]);
  }
  // Appends the track, cameras ascending, to the scene.
  void commit(const double X[3], Scene *scene) {
    order.resize(cams.size());
    for (std::size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
    std::sort(order.begin(), order.end(), [&](int a, int b) { return cams[a] < cams[b]; });
    for (int k : order) {
      scene->track_cameras.push_back(cams[k]);
      scene->true_x.push_back(xs[2 * k]);
      scene->true_x.push_back(xs[2 * k + 1]);
    }
    scene->true_points.insert(scene->true_points.end(), X, X + 3);
    scene->track_begin.push_back(scene->track_cameras.size());
  }
};

constexpr int kMaxAttempts = 2000;  // placements tried for one point before giving up
constexpr int kAttemptsPerLength = 100;  // placements tried with one track length
constexpr int kEnumerateCameras = 64;  // Orbit: up to this many cameras, test them all

// Orbit: a point uniform in the unit ball, seen by a random subset of L of the cameras that
// see it (fewer when fewer see it, but at least track_min).
bool orbit_point(const Options &o, const Visibility &vis, int L, Random &rng, TrackBuilder *tb, double X[3],
                 std::vector<int> *visible, std::vector<double> *visible_x, std::vector<char> *tried) {
  do {
    for (int a = 0; a < 3; ++a) X[a] = rng.uniform(-1, 1);
  } while (X[0] * X[0] + X[1] * X[1] + X[2] * X[2] > 1);
  const int m = o.cameras;
  tb->clear();
  double x[2];
  if (m <= kEnumerateCameras) {
    visible->clear();
    visible_x->clear();
    for (int j = 0; j < m; ++j)
      if (vis.sees(j, X, x)) {
        visible->push_back(j);
        visible_x->push_back(x[0]);
        visible_x->push_back(x[1]);
      }
    const int nv = static_cast<int>(visible->size());
    if (nv < o.track_min) return false;
    const int take = std::min(L, nv);
    for (int k = 0; k < take; ++k) {  // partial Fisher-Yates
      const int r = k + static_cast<int>(rng.below(static_cast<std::uint64_t>(nv - k)));
      std::swap((*visible)[k], (*visible)[r]);
      std::swap((*visible_x)[2 * k], (*visible_x)[2 * r]);
      std::swap((*visible_x)[2 * k + 1], (*visible_x)[2 * r + 1]);
      tb->add((*visible)[k], &(*visible_x)[2 * k]);
    }
    return true;
  }
  // Many cameras: draw random ones, each at most once, until L see the point or the budget
  // is spent. The cameras tried are marked in *tried (m entries, left all zero), so that a
  // long track costs time in its length, not its square.
  visible->clear();  // here: the cameras already tried
  tried->resize(static_cast<std::size_t>(m));
  const int budget = 8 * L + 32;
  for (int d = 0; d < budget && static_cast<int>(tb->cams.size()) < L; ++d) {
    const int j = static_cast<int>(rng.below(static_cast<std::uint64_t>(m)));
    if ((*tried)[j]) continue;
    (*tried)[j] = 1;
    visible->push_back(j);
    if (vis.sees(j, X, x)) tb->add(j, x);
  }
  for (int j : *visible) (*tried)[j] = 0;
  return static_cast<int>(tb->cams.size()) >= o.track_min;
}

// Path: a random run of L consecutive cameras; the point is placed in the view of one of
// them, at a depth in [2, 12] steps, and kept if all of the run see it (at depths of at least
// 2 steps: a point brushing past a camera is not kept).
bool path_point(const Options &o, const Visibility &vis, const std::vector<Camera> &cams, int L, Random &rng,
                TrackBuilder *tb, double X[3]) {
  const int m = o.cameras;
  const int j0 = rng.between(0, m - L);
  const int ref = rng.between(j0, j0 + L - 1);
  const Camera &c = cams[ref];
  const double xn = rng.uniform(-c.k.u0, o.image_width - 1 - c.k.u0) / c.k.fu;
  const double yn = rng.uniform(-c.k.v0, o.image_height - 1 - c.k.v0) / (c.k.fu * c.k.ar);
  const double depth = rng.uniform(kPathDepthMin, kPathDepthMax);
  const double Xc[3] = {xn * depth - c.t[0], yn * depth - c.t[1], depth - c.t[2]};
  double R[9];
  euclidean::rotation_matrix(c.q, R);
  for (int a = 0; a < 3; ++a) X[a] = R[a] * Xc[0] + R[3 + a] * Xc[1] + R[6 + a] * Xc[2];  // R^T (Xc - t)
  tb->clear();
  double x[2];
  for (int j = j0; j < j0 + L; ++j) {
    if (!vis.sees(j, X, x)) return false;
    tb->add(j, x);
  }
  return true;
}

// ---- measurements ----

// Noise for one measurement: isotropic sigma, or drawn from a random covariance written to cov.
void draw_noise(const Options &o, Random &rng, double e[2], double *cov) {
  if (!cov) {
    e[0] = o.noise * rng.normal();
    e[1] = o.noise * rng.normal();
    return;
  }
  const double s1 = o.noise * rng.uniform(0.5, 2.0), s2 = o.noise * rng.uniform(0.5, 2.0);
  const double angle = rng.uniform(0, kPi);
  const double c = std::cos(angle), s = std::sin(angle);
  // C = Q diag(s1^2, s2^2) Q^T with Q = [c -s; s c]; e = Q (s1 z1, s2 z2) has covariance C.
  cov[0] = c * c * s1 * s1 + s * s * s2 * s2;
  cov[1] = cov[2] = c * s * (s1 * s1 - s2 * s2);
  cov[3] = s * s * s1 * s1 + c * c * s2 * s2;
  const double z1 = s1 * rng.normal(), z2 = s2 * rng.normal();
  e[0] = c * z1 - s * z2;
  e[1] = s * z1 + c * z2;
}

bool inside(const Options &o, const double x[2]) {
  return x[0] >= 0 && x[0] <= o.image_width - 1 && x[1] >= 0 && x[1] <= o.image_height - 1;
}

// The n points and their tracks, seen by the cameras of s as vis says.
bool place_points(const Options &o, const Visibility &vis, Random &rng, Scene *s, std::string *error) {
  const int m = o.cameras, n = o.points;
  const std::size_t expected = static_cast<std::size_t>(n) * ((o.track_min + std::min(o.track_max, m)) / 2 + 1);
  s->true_points.reserve(3 * static_cast<std::size_t>(n));
  s->track_begin.reserve(static_cast<std::size_t>(n) + 1);
  s->track_cameras.reserve(expected);
  s->true_x.reserve(2 * expected);
  s->track_begin.push_back(0);
  TrackBuilder tb;
  std::vector<int> scratch;
  std::vector<double> scratch_x;
  std::vector<char> tried;
  for (int i = 0; i < n; ++i) {
    double X[3];
    // The track length is drawn first and kept while placements fail, so that the lengths
    // that are harder to place (long runs on a path) are not under-represented; after
    // kAttemptsPerLength failures it is drawn again.
    int L = 0;
    for (int attempt = 0;; ++attempt) {
      if (attempt == kMaxAttempts)
        return fail(error, "could not place point " + std::to_string(i) + " in " + std::to_string(kMaxAttempts) +
                               " attempts: the cameras do not see enough of the scene for tracks of " +
                               std::to_string(o.track_min) + ".." + std::to_string(o.track_max));
      if (attempt % kAttemptsPerLength == 0)
        L = o.trajectory == Trajectory::Photo ? photo_track_length(o, rng)
                                              : rng.between(o.track_min, std::min(o.track_max, m));
      // A photo collection's points are the landmark's, seen as the orbit's are.
      const bool ok = o.trajectory == Trajectory::Path ? path_point(o, vis, s->true_cameras, L, rng, &tb, X)
                                                       : orbit_point(o, vis, L, rng, &tb, X, &scratch, &scratch_x, &tried);
      if (ok) break;
    }
    tb.commit(X, s);
  }
  return true;
}

// The measurements: the true projections with noise (redrawn in the rare case it leaves the
// image).
void add_noise(const Options &o, Random &rng, Scene *s) {
  const std::size_t N = s->track_cameras.size();
  eucsba::PointSet &ps = s->measurements;
  ps.ncameras = o.cameras;
  ps.form = o.covariances ? eucsba::CovarianceForm::UpperTriangular : eucsba::CovarianceForm::None;
  ps.x.resize(2 * N);
  if (o.covariances) ps.covx.resize(4 * N);
  for (std::size_t k = 0; k < N; ++k) {
    double *x = &ps.x[2 * k];
    const double *xt = &s->true_x[2 * k];
    if (o.noise == 0) {
      x[0] = xt[0];
      x[1] = xt[1];
      continue;
    }
    do {
      double e[2];
      draw_noise(o, rng, e, o.covariances ? &ps.covx[4 * k] : nullptr);
      x[0] = xt[0] + e[0];
      x[1] = xt[1] + e[1];
    } while (!inside(o, x));
  }
}

// --outliers of the measurements replaced by points of the image at least a few sigma_max
// from the truth.
void add_outliers(const Options &o, double sigma_max, Random &rng, Scene *s) {
  const std::size_t N = s->track_cameras.size();
  eucsba::PointSet &ps = s->measurements;
  s->outlier.assign(N, 0);
  const auto want = static_cast<std::size_t>(std::llround(o.outliers * static_cast<double>(N)));
  const double min_dist = std::min(std::max(5.0, 10 * sigma_max), 0.25 * std::min(o.image_width, o.image_height));
  std::size_t left = want;
  for (std::size_t k = 0; k < N && left > 0; ++k) {
    // Selection sampling: each measurement is taken with probability left / remaining.
    if (rng.below(N - k) >= left) continue;
    --left;
    s->outlier[k] = 1;
    double *x = &ps.x[2 * k];
    const double *xt = &s->true_x[2 * k];
    do {
      x[0] = rng.uniform(0, o.image_width - 1);
      x[1] = rng.uniform(0, o.image_height - 1);
    } while (std::hypot(x[0] - xt[0], x[1] - xt[1]) < min_dist);
  }
}

// The initial estimate: the true cameras and points, perturbed.
void perturb(const Options &o, Random &rng, Scene *s) {
  s->initial_cameras = s->true_cameras;
  for (Camera &c : s->initial_cameras) {
    const double wx = o.perturb_rotation * rng.normal(), wy = o.perturb_rotation * rng.normal(),
                 wz = o.perturb_rotation * rng.normal();
    // Turn the camera about its own centre C = -R^T t (not about the world origin, which
    // may be far away on a path), then shift t.
    double R[9];
    euclidean::rotation_matrix(c.q, R);
    double C[3];
    for (int a = 0; a < 3; ++a) C[a] = -(R[a] * c.t[0] + R[3 + a] * c.t[1] + R[6 + a] * c.t[2]);
    c.q = euclidean::normalized_rotation(euclidean::multiply(small_rotation(wx, wy, wz), c.q));
    euclidean::rotation_matrix(c.q, R);
    for (int r = 0; r < 3; ++r)
      c.t[r] = -(R[3 * r] * C[0] + R[3 * r + 1] * C[1] + R[3 * r + 2] * C[2]) +
               o.perturb_translation * s->scene_scale * rng.normal();
    if (o.kind == CameraKind::FixedIntrinsics) continue;
    c.k.fu *= 1 + o.perturb_intrinsics * rng.normal();
    c.k.u0 *= 1 + o.perturb_intrinsics * rng.normal();
    c.k.v0 *= 1 + o.perturb_intrinsics * rng.normal();
    if (o.kind != CameraKind::VaryingIntrinsicsDistortion) continue;
    c.kc[0] += o.perturb_intrinsics * rng.normal();
    c.kc[1] += o.perturb_intrinsics * rng.normal();
  }
  eucsba::PointSet &ps = s->measurements;
  ps.xyz = s->true_points;
  for (double &v : ps.xyz) v += o.perturb_points * s->scene_scale * rng.normal();
}

}  // namespace

// ---- generate ----

bool generate(const Options &o, Scene *scene, std::string *error) {
  if (!o.IsValid(error)) return false;
  Random rng(o.seed);
  Scene s;
  s.kind = o.kind;
  s.image_width = o.image_width;
  s.image_height = o.image_height;
  s.scene_scale = 1;  // the generator works in scene units

  const int m = o.cameras, n = o.points;
  s.true_cameras.resize(m);
  const Lens lens = base_lens(o, rng);
  for (Camera &c : s.true_cameras) camera_lens(o, lens, rng, &c);
  switch (o.trajectory) {
    case Trajectory::Orbit: orbit_cameras(o, rng, &s.true_cameras); break;
    case Trajectory::Path: path_cameras(o, rng, &s.true_cameras); break;
    case Trajectory::Photo: photo_cameras(o, rng, &s.true_cameras); break;
  }

  // Projections stay this far inside the image so that the noise rarely takes them out.
  const double sigma_max = o.covariances ? 2 * o.noise : o.noise;
  const double margin = std::max(1.0, 5 * sigma_max);
  const double min_depth = o.trajectory == Trajectory::Path ? kPathDepthMin : 0.1;
  const Visibility vis(o.kind, s.true_cameras, o.image_width, o.image_height, margin, min_depth);
  if (!place_points(o, vis, rng, &s, error)) return false;
  add_noise(o, rng, &s);
  add_outliers(o, sigma_max, rng, &s);
  perturb(o, rng, &s);
  if (o.dense_vmask_limit > 0 && static_cast<std::size_t>(n) * static_cast<std::size_t>(m) <= o.dense_vmask_limit)
    s.measurements.vmask = dense_vmask(s);

  *scene = std::move(s);
  return true;
}

std::vector<char> dense_vmask(const Scene &scene) {
  const std::size_t m = static_cast<std::size_t>(scene.ncameras());
  std::vector<char> vmask(static_cast<std::size_t>(scene.npoints()) * m, 0);
  for (int i = 0; i < scene.npoints(); ++i)
    for (std::size_t k = scene.track_begin[i]; k < scene.track_begin[i + 1]; ++k)
      vmask[static_cast<std::size_t>(i) * m + static_cast<std::size_t>(scene.track_cameras[k])] = 1;
  return vmask;
}

// ---- files ----

namespace {

struct FileCloser {
  void operator()(std::FILE *f) const {
    if (f) std::fclose(f);
  }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

// "<path>: <message>", the formats' form of an error that concerns no line.
bool fail(std::string *error, const std::string &path, const std::string &message) {
  *error = path + ": " + message;
  return false;
}

bool open_for_writing(const std::string &path, File *f, std::string *error) {
  f->reset(std::fopen(path.c_str(), "w"));
  if (!*f) return fail(error, path, std::string("cannot open for writing: ") + std::strerror(errno));
  return true;
}

bool close_written(const std::string &path, File *f, std::string *error) {
  const bool bad = std::ferror(f->get()) != 0;
  const bool close_failed = std::fclose(f->release()) != 0;
  if (bad || close_failed) return fail(error, path, "write failed");
  return true;
}

}  // namespace

ProblemFiles problem_files(const std::string &prefix, const Scene &scene) {
  ProblemFiles f;
  f.cams = prefix + "-cams.txt";
  f.pts = prefix + "-pts.txt";
  if (scene.kind == CameraKind::FixedIntrinsics) f.calib = prefix + "-calib.txt";
  f.truth_cams = prefix + "-truth-cams.txt";
  f.truth_pts = prefix + "-truth-pts.txt";
  if (scene.noutliers() > 0) f.outliers = prefix + "-outliers.txt";
  return f;
}

bool write_calibration(const std::string &path, const euclidean::Intrinsics &k, std::string *error) {
  File f;
  if (!open_for_writing(path, &f, error)) return false;
  std::fputs("# K = [fu s u0; 0 fv v0; 0 0 1]\n", f.get());
  std::fprintf(f.get(), "%.10e %.10e %.10e\n", k.fu, k.s, k.u0);
  std::fprintf(f.get(), "0 %.10e %.10e\n", k.fu * k.ar, k.v0);
  std::fputs("0 0 1\n", f.get());
  return close_written(path, &f, error);
}

bool write_points_sparse(const std::string &path, const Scene &scene, const std::vector<double> &xyz,
                         const std::vector<double> &x, std::string *error) {
  const std::size_t N = scene.nprojections();
  if (xyz.size() != scene.true_points.size() || x.size() != 2 * N)
    return fail(error, path, "internal error: coordinates or projections do not match the scene");
  const eucsba::CovarianceForm form =
      scene.measurements.has_covariances() ? scene.measurements.form : eucsba::CovarianceForm::None;
  const std::vector<double> &covx = scene.measurements.covx;
  File f;
  if (!open_for_writing(path, &f, error)) return false;
  std::fputs("# X Y Z  nframes  frame0 x0 y0", f.get());
  if (form == eucsba::CovarianceForm::UpperTriangular) std::fputs(" cxx0 cxy0 cyy0", f.get());
  if (form == eucsba::CovarianceForm::Full) std::fputs(" cxx0 cxy0 cxy0 cyy0", f.get());
  std::fputs("  frame1 ...\n", f.get());
  for (int i = 0; i < scene.npoints(); ++i) {
    const std::size_t b = scene.track_begin[i], e = scene.track_begin[i + 1];
    std::fprintf(f.get(), "%.10e %.10e %.10e %d", xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2], static_cast<int>(e - b));
    for (std::size_t k = b; k < e; ++k) {
      std::fprintf(f.get(), "  %d %.10e %.10e", scene.track_cameras[k], x[2 * k], x[2 * k + 1]);
      const double *c = form != eucsba::CovarianceForm::None ? &covx[4 * k] : nullptr;
      if (form == eucsba::CovarianceForm::UpperTriangular)
        std::fprintf(f.get(), " %.10e %.10e %.10e", c[0], c[1], c[3]);
      else if (form == eucsba::CovarianceForm::Full)
        std::fprintf(f.get(), " %.10e %.10e %.10e %.10e", c[0], c[1], c[2], c[3]);
    }
    std::fputc('\n', f.get());
  }
  return close_written(path, &f, error);
}

bool write_problem(const Scene &scene, const std::string &prefix, std::string *error) {
  const ProblemFiles files = problem_files(prefix, scene);
  if (!eucsba::write_cameras(files.cams, scene.kind, scene.initial_cameras, error)) return false;
  if (!eucsba::write_cameras(files.truth_cams, scene.kind, scene.true_cameras, error)) return false;
  if (!files.calib.empty())
    if (!write_calibration(files.calib, scene.true_cameras.at(0).k, error)) return false;

  const eucsba::PointSet &ps = scene.measurements;
  if (scene.has_dense_vmask()) {
    if (!eucsba::write_points(files.pts, ps, ps.xyz, error)) return false;
    eucsba::PointSet truth;  // the same tracks with the exact projections
    truth.ncameras = ps.ncameras;
    truth.form = ps.form;
    truth.xyz = scene.true_points;
    truth.vmask = ps.vmask;
    truth.x = scene.true_x;
    truth.covx = ps.covx;
    if (!eucsba::write_points(files.truth_pts, truth, truth.xyz, error)) return false;
  } else {
    if (!write_points_sparse(files.pts, scene, ps.xyz, ps.x, error)) return false;
    if (!write_points_sparse(files.truth_pts, scene, scene.true_points, scene.true_x, error)) return false;
  }

  if (!files.outliers.empty()) {
    File f;
    if (!open_for_writing(files.outliers, &f, error)) return false;
    std::fputs("# point camera: the measurements of the points file that are gross outliers\n", f.get());
    for (int i = 0; i < scene.npoints(); ++i)
      for (std::size_t k = scene.track_begin[i]; k < scene.track_begin[i + 1]; ++k)
        if (scene.outlier[k]) std::fprintf(f.get(), "%d %d\n", i, scene.track_cameras[k]);
    if (!close_written(files.outliers, &f, error)) return false;
  }
  return true;
}

}  // namespace sbagen
