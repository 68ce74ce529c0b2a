// SPDX-License-Identifier: BSD-3-Clause
// Tests of the scene generator (lib/generator/sbagen.h): determinism, counts, geometry of
// the truth, tracks, noise and covariance statistics, outliers, the files it writes, and that
// sba refines a generated problem back to its ground truth; the sbagen program's COLMAP and
// Bundler files.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "cameras/euclidean.h"
#include "colmap_fixtures.h"
#include "formats/bundler_io.h"
#include "formats/colmap_io.h"
#include "formats/eucsba_io.h"
#include "generator/sbagen.h"
#include "sba.h"

namespace eucsba = sbaformats::eucsba;
namespace colmap = sbaformats::colmap;
namespace bundler = sbaformats::bundler;
namespace euclidean = sbacameras::euclidean;

namespace {

using euclidean::Camera;
using euclidean::CameraKind;
using sbagen::Options;
using sbagen::Scene;
using sbagen::Trajectory;

Options small_orbit() {
  Options o;
  o.cameras = 10;
  o.points = 300;
  o.track_min = 2;
  o.track_max = 8;
  o.seed = 7;
  return o;
}

Options small_path() {
  Options o;
  o.trajectory = Trajectory::Path;
  o.cameras = 30;
  o.points = 400;
  o.track_min = 3;
  o.track_max = 6;
  o.seed = 11;
  return o;
}

Options small_photo() {
  Options o;
  o.trajectory = Trajectory::Photo;
  o.cameras = 40;
  o.points = 2000;
  o.track_min = 3;
  o.track_max = 40;
  o.seed = 5;
  return o;
}

Scene make(const Options &o) {
  Scene s;
  std::string why;
  EXPECT_TRUE(sbagen::generate(o, &s, &why)) << why;
  return s;
}

void rotation(const Camera &c, double R[9]) { euclidean::rotation_matrix(c.q, R); }

// Camera centre C = -R^T t.
std::array<double, 3> centre(const Camera &c) {
  double R[9];
  rotation(c, R);
  std::array<double, 3> C{};
  for (int a = 0; a < 3; ++a) C[a] = -(R[a] * c.t[0] + R[3 + a] * c.t[1] + R[6 + a] * c.t[2]);
  return C;
}

// Depth of X in camera c.
double depth(const Camera &c, const double *X) {
  double R[9];
  rotation(c, R);
  return R[6] * X[0] + R[7] * X[1] + R[8] * X[2] + c.t[2];
}

// Angle of the rotation R_a^T R_b.
double angle_between(const double Ra[9], const double Rb[9]) {
  double tr = 0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) tr += Ra[3 * r + c] * Rb[3 * r + c];
  return std::acos(std::clamp(0.5 * (tr - 1), -1.0, 1.0));
}

// Relative rotation R_j R_0^T (invariant under a similarity of the scene).
void relative_rotation(const Camera &cj, const Camera &c0, double out[9]) {
  double Rj[9], R0[9];
  rotation(cj, Rj);
  rotation(c0, R0);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      double v = 0;
      for (int k = 0; k < 3; ++k) v += Rj[3 * r + k] * R0[3 * c + k];
      out[3 * r + c] = v;
    }
}

double dist(const double *a, const double *b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

// The shape of a reconstruction, free of the gauge: the distances between camera centres and
// from every point to every camera centre, divided by the RMS distance of the centres from
// their centroid. Equal shapes mean the reconstructions differ by a similarity transform.
struct Shape {
  std::vector<double> camera_distances;  // m*m
  std::vector<double> point_distances;   // n*m
};

Shape shape(const std::vector<Camera> &cams, const std::vector<double> &pts) {
  const std::size_t m = cams.size(), n = pts.size() / 3;
  std::vector<std::array<double, 3>> C(m);
  std::array<double, 3> mean{};
  for (std::size_t j = 0; j < m; ++j) {
    C[j] = centre(cams[j]);
    for (int a = 0; a < 3; ++a) mean[a] += C[j][a] / m;
  }
  double s = 0;
  for (std::size_t j = 0; j < m; ++j) s += dist(C[j].data(), mean.data()) * dist(C[j].data(), mean.data()) / m;
  s = std::sqrt(s);
  Shape out;
  for (std::size_t j = 0; j < m; ++j)
    for (std::size_t k = 0; k < m; ++k) out.camera_distances.push_back(dist(C[j].data(), C[k].data()) / s);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < m; ++j) out.point_distances.push_back(dist(&pts[3 * i], C[j].data()) / s);
  return out;
}

double max_abs_diff(const std::vector<double> &a, const std::vector<double> &b) {
  double d = 0;
  for (std::size_t k = 0; k < a.size(); ++k) d = std::max(d, std::fabs(a[k] - b[k]));
  return d;
}

double rms_diff(const std::vector<double> &a, const std::vector<double> &b) {
  double d = 0;
  for (std::size_t k = 0; k < a.size(); ++k) d += (a[k] - b[k]) * (a[k] - b[k]);
  return std::sqrt(d / a.size());
}

// Largest angle between relative rotations R_j R_0^T of two camera sets.
double max_relative_rotation_error(const std::vector<Camera> &a, const std::vector<Camera> &b) {
  double worst = 0;
  for (std::size_t j = 1; j < a.size(); ++j) {
    double Ra[9], Rb[9];
    relative_rotation(a[j], a[0], Ra);
    relative_rotation(b[j], b[0], Rb);
    worst = std::max(worst, angle_between(Ra, Rb));
  }
  return worst;
}

struct Solution {
  int ret = SBA_ERROR;
  double info[SBA_INFOSZ] = {};
  std::vector<Camera> cameras;
  std::vector<double> points;
};

// Motion and structure refinement from the scene's initial estimate with the expert driver
// and the demo's analytic Jacobian, eucsbademo's defaults (mcon = ncon = 0).
Solution solve(const Scene &s) {
  const euclidean::CameraModel model(s.kind, s.initial_cameras, s.initial_points());
  const int m = s.ncameras(), n = s.npoints(), cnp = model.cnp();
  std::vector<double> p = model.initial_camera_params();
  p.insert(p.end(), s.initial_points().begin(), s.initial_points().end());
  std::vector<char> vmask = s.has_dense_vmask() ? s.measurements.vmask : sbagen::dense_vmask(s);
  std::vector<double> x = s.measurements.x;
  std::vector<double> covx = s.measurements.covx;
  const euclidean::ExpertCallbacks cb = euclidean::expert_callbacks(s.kind, euclidean::Refinement::MotionStructure);
  double opts[SBA_OPTSSZ] = {SBA_INIT_MU, SBA_STOP_THRESH, SBA_STOP_THRESH, SBA_STOP_THRESH, 0.0};
  Solution out;
  out.ret = sba_motstr_levmar_x(n, 0, m, 0, vmask.data(), p.data(), cnp, euclidean::kPointParams, x.data(),
                                covx.empty() ? nullptr : covx.data(), euclidean::kMeasurementParams, cb.func, cb.fjac,
                                euclidean::as_adata(model), 150, 0, opts, out.info);
  for (int j = 0; j < m; ++j) out.cameras.push_back(model.camera(j, p.data() + static_cast<std::size_t>(j) * cnp));
  out.points.assign(p.begin() + static_cast<std::ptrdiff_t>(m) * cnp, p.end());
  return out;
}

// A scratch directory removed at the end of the test.
class TempDir {
 public:
  explicit TempDir(const std::string &name)
      : path_(std::filesystem::path(::testing::TempDir()) /
              ("sbagen-" + name + "-" + std::to_string(static_cast<long>(::getpid())))) {
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  std::string file(const std::string &name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

std::string slurp(const std::string &path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// ---- Random ----

TEST(SbagenRandom, EngineIsTheStandardMersenneTwister) {
  // The C++ standard fixes the 10000th output of mt19937_64 seeded with 5489.
  sbagen::Random r(5489);
  std::uint64_t v = 0;
  for (int k = 0; k < 10000; ++k) v = r.bits();
  EXPECT_EQ(v, 9981545732273789042ULL);
}

TEST(SbagenRandom, DrawsFollowTheirDistributions) {
  sbagen::Random r(3);
  const int N = 200000;
  double sum = 0, sum2 = 0, umin = 1, umax = 0;
  std::vector<int> counts(7, 0);
  for (int k = 0; k < N; ++k) {
    const double u = r.uniform();
    umin = std::min(umin, u);
    umax = std::max(umax, u);
    const std::uint64_t b = r.below(7);
    ASSERT_LT(b, 7u);
    ++counts[b];
    const int i = r.between(-2, 2);
    ASSERT_GE(i, -2);
    ASSERT_LE(i, 2);
    const double z = r.normal();
    sum += z;
    sum2 += z * z;
  }
  EXPECT_GE(umin, 0.0);
  EXPECT_LT(umax, 1.0);
  for (int c : counts) EXPECT_NEAR(c, N / 7.0, 5 * std::sqrt(N / 7.0));
  EXPECT_NEAR(sum / N, 0.0, 0.01);
  EXPECT_NEAR(sum2 / N, 1.0, 0.02);
}

// ---- options ----

TEST(SbagenOptions, DefaultsAreValid) {
  std::string why;
  EXPECT_TRUE(Options().IsValid(&why)) << why;
}

TEST(SbagenOptions, BadOptionsAreRefusedWithAReason) {
  auto refused = [](Options o) {
    std::string why;
    const bool valid = o.IsValid(&why);
    Scene s;
    std::string gen_why;
    const bool generated = sbagen::generate(o, &s, &gen_why);
    return !valid && !why.empty() && !generated && gen_why == why;
  };
  Options o;
  o.cameras = 1;
  EXPECT_TRUE(refused(o));
  o = Options();
  o.points = 0;
  EXPECT_TRUE(refused(o));
  o = Options();
  o.track_min = 1;
  EXPECT_TRUE(refused(o));
  o = Options();
  o.track_min = 5;
  o.track_max = 4;
  EXPECT_TRUE(refused(o));
  o = Options();
  o.cameras = 3;
  o.track_min = 4;
  o.track_max = 4;
  EXPECT_TRUE(refused(o));
  o = Options();
  o.noise = -1;
  EXPECT_TRUE(refused(o));
  o = Options();
  o.noise = 0;
  o.covariances = true;
  EXPECT_TRUE(refused(o));
  o = Options();
  o.outliers = 1.5;
  EXPECT_TRUE(refused(o));
  o = Options();
  o.perturb_rotation = NAN;
  EXPECT_TRUE(refused(o));
  o = Options();
  o.image_width = 8;
  EXPECT_TRUE(refused(o));
  o = Options();
  o.orbit_arc_deg = 0;
  EXPECT_TRUE(refused(o));
  o = Options();
  o.points = 1 << 30;
  EXPECT_TRUE(refused(o));
}

TEST(SbagenOptions, ImpossibleTracksFailCleanly) {
  // Sideways views with a long lens: ten consecutive cameras cannot all see a point.
  Options o = small_path();
  o.path_yaw_deg = 90;
  o.focal = 5000;
  o.track_min = o.track_max = 10;
  Scene s;
  std::string why;
  EXPECT_FALSE(sbagen::generate(o, &s, &why));
  EXPECT_NE(why.find("could not place point"), std::string::npos) << why;
}

// ---- determinism ----

void expect_same_cameras(const std::vector<Camera> &a, const std::vector<Camera> &b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t j = 0; j < a.size(); ++j) {
    EXPECT_EQ(a[j].q.w, b[j].q.w);
    EXPECT_EQ(a[j].q.x, b[j].q.x);
    EXPECT_EQ(a[j].q.y, b[j].q.y);
    EXPECT_EQ(a[j].q.z, b[j].q.z);
    EXPECT_EQ(a[j].t, b[j].t);
    EXPECT_EQ(a[j].kc, b[j].kc);
    EXPECT_EQ(a[j].k.fu, b[j].k.fu);
    EXPECT_EQ(a[j].k.u0, b[j].k.u0);
    EXPECT_EQ(a[j].k.v0, b[j].k.v0);
  }
}

void expect_same(const Scene &a, const Scene &b) {
  expect_same_cameras(a.true_cameras, b.true_cameras);
  expect_same_cameras(a.initial_cameras, b.initial_cameras);
  EXPECT_EQ(a.true_points, b.true_points);
  EXPECT_EQ(a.track_begin, b.track_begin);
  EXPECT_EQ(a.track_cameras, b.track_cameras);
  EXPECT_EQ(a.true_x, b.true_x);
  EXPECT_EQ(a.measurements.xyz, b.measurements.xyz);
  EXPECT_EQ(a.measurements.x, b.measurements.x);
  EXPECT_EQ(a.measurements.covx, b.measurements.covx);
  EXPECT_EQ(a.measurements.vmask, b.measurements.vmask);
  EXPECT_EQ(a.outlier, b.outlier);
}

TEST(SbagenDeterminism, SameSeedSameSceneOtherSeedOtherScene) {
  for (Options o : {small_orbit(), small_path(), small_photo()}) {
    o.kind = CameraKind::VaryingIntrinsicsDistortion;
    o.covariances = true;
    o.outliers = 0.05;
    const Scene a = make(o), b = make(o);
    expect_same(a, b);
    o.seed += 1;
    const Scene c = make(o);
    EXPECT_NE(a.true_points, c.true_points);
    EXPECT_NE(a.measurements.x, c.measurements.x);
  }
}

TEST(SbagenDeterminism, DenseVmaskLimitChangesNothingElse) {
  Options o = small_orbit();
  const Scene dense = make(o);
  o.dense_vmask_limit = 0;
  const Scene sparse = make(o);
  EXPECT_TRUE(dense.has_dense_vmask());
  EXPECT_FALSE(sparse.has_dense_vmask());
  EXPECT_EQ(dense.measurements.vmask, sbagen::dense_vmask(sparse));
  EXPECT_EQ(dense.measurements.x, sparse.measurements.x);
  EXPECT_EQ(dense.track_cameras, sparse.track_cameras);
}

// ---- structure of a scene ----

void check_structure(const Options &o, const Scene &s) {
  const int m = o.cameras, n = o.points;
  ASSERT_EQ(s.ncameras(), m);
  ASSERT_EQ(s.npoints(), n);
  ASSERT_EQ(s.initial_cameras.size(), static_cast<std::size_t>(m));
  ASSERT_EQ(s.track_begin.size(), static_cast<std::size_t>(n) + 1);
  const std::size_t N = s.nprojections();
  EXPECT_EQ(s.track_begin.front(), 0u);
  EXPECT_EQ(s.track_begin.back(), N);
  EXPECT_EQ(s.true_x.size(), 2 * N);
  EXPECT_EQ(s.outlier.size(), N);
  const eucsba::PointSet &ps = s.measurements;
  EXPECT_EQ(ps.ncameras, m);
  EXPECT_EQ(ps.npoints(), n);
  EXPECT_EQ(static_cast<std::size_t>(ps.nprojections()), N);
  EXPECT_EQ(ps.covx.size(), o.covariances ? 4 * N : 0u);
  EXPECT_EQ(ps.form, o.covariances ? eucsba::CovarianceForm::UpperTriangular : eucsba::CovarianceForm::None);
  EXPECT_EQ(s.kind, o.kind);
  EXPECT_EQ(s.image_width, o.image_width);
  EXPECT_EQ(s.image_height, o.image_height);
  if (s.has_dense_vmask()) {
    ASSERT_EQ(ps.vmask.size(), static_cast<std::size_t>(n) * m);
    EXPECT_EQ(static_cast<std::size_t>(std::count(ps.vmask.begin(), ps.vmask.end(), 1)), N);
    EXPECT_EQ(ps.vmask, sbagen::dense_vmask(s));
  }
  const int longest = std::min(o.track_max, m);
  for (int i = 0; i < n; ++i) {
    const std::size_t b = s.track_begin[i], e = s.track_begin[i + 1];
    ASSERT_GE(e - b, static_cast<std::size_t>(o.track_min)) << "point " << i;
    ASSERT_LE(e - b, static_cast<std::size_t>(longest)) << "point " << i;
    for (std::size_t k = b; k < e; ++k) {
      ASSERT_GE(s.track_cameras[k], 0);
      ASSERT_LT(s.track_cameras[k], m);
      if (k > b) {
        ASSERT_LT(s.track_cameras[k - 1], s.track_cameras[k]) << "cameras ascending, point " << i;
        if (o.trajectory == Trajectory::Path) {
          ASSERT_EQ(s.track_cameras[k - 1] + 1, s.track_cameras[k]) << "consecutive cameras, point " << i;
        }
      }
    }
  }
  for (const Camera &c : s.true_cameras) {
    EXPECT_NEAR(c.q.w * c.q.w + c.q.x * c.q.x + c.q.y * c.q.y + c.q.z * c.q.z, 1.0, 1e-12);
    EXPECT_GE(c.q.w, 0.0);
    if (o.kind == CameraKind::FixedIntrinsics) {
      EXPECT_EQ(c.k.fu, s.true_cameras[0].k.fu);
      EXPECT_EQ(c.k.u0, s.true_cameras[0].k.u0);
      EXPECT_EQ(c.kc, (std::array<double, 5>{}));
    }
  }
}

// Every truth projection is in front of its camera, inside the image, and what the demo's
// model gives for the true camera and point.
void check_truth_projections(const Scene &s) {
  const euclidean::CameraModel truth(s.kind, s.true_cameras, s.true_points);
  for (int i = 0; i < s.npoints(); ++i)
    for (std::size_t k = s.track_begin[i]; k < s.track_begin[i + 1]; ++k) {
      const int j = s.track_cameras[k];
      ASSERT_GT(depth(s.true_cameras[j], &s.true_points[3 * i]), 0.0) << "point " << i << " camera " << j;
      double x[2];
      truth.project(j, truth.initial_camera(j), truth.initial_point(i), x);
      ASSERT_NEAR(x[0], s.true_x[2 * k], 1e-9);
      ASSERT_NEAR(x[1], s.true_x[2 * k + 1], 1e-9);
      for (const double *p : {&s.true_x[2 * k], &s.measurements.x[2 * k]}) {
        ASSERT_GE(p[0], 0.0);
        ASSERT_LE(p[0], s.image_width - 1.0);
        ASSERT_GE(p[1], 0.0);
        ASSERT_LE(p[1], s.image_height - 1.0);
      }
    }
}

TEST(SbagenScene, OrbitOfEveryKind) {
  for (CameraKind kind :
       {CameraKind::FixedIntrinsics, CameraKind::VaryingIntrinsics, CameraKind::VaryingIntrinsicsDistortion}) {
    Options o = small_orbit();
    o.kind = kind;
    const Scene s = make(o);
    check_structure(o, s);
    check_truth_projections(s);
  }
}

TEST(SbagenScene, OrbitCamerasLookAtTheCentre) {
  const Scene s = make(small_orbit());
  const double origin[3] = {0, 0, 0};
  for (const Camera &c : s.true_cameras) {
    const double Z = depth(c, origin);
    ASSERT_GT(Z, 0.0);
    EXPECT_LT(std::hypot(c.t[0] / Z, c.t[1] / Z), 0.1);  // the centre projects near the principal point
  }
}

TEST(SbagenScene, PathTracksAreConsecutive) {
  for (CameraKind kind : {CameraKind::FixedIntrinsics, CameraKind::VaryingIntrinsicsDistortion}) {
    Options o = small_path();
    o.kind = kind;
    const Scene s = make(o);
    check_structure(o, s);
    check_truth_projections(s);
  }
  Options side = small_path();
  side.path_yaw_deg = 90;
  side.track_min = 2;
  side.track_max = 4;
  const Scene s = make(side);
  check_structure(side, s);
  check_truth_projections(s);
}

TEST(SbagenScene, TrackLengthsCoverTheRange) {
  for (Options o : {small_orbit(), small_path()}) {
    o.points = 2000;
    const Scene s = make(o);
    std::vector<int> hist(o.track_max + 1, 0);
    for (int i = 0; i < s.npoints(); ++i) ++hist[s.track_begin[i + 1] - s.track_begin[i]];
    for (int L = o.track_min; L <= o.track_max; ++L)
      EXPECT_GT(hist[L], o.points / (o.track_max - o.track_min + 1) / 2) << "length " << L;
  }
}

// A photo collection: every camera sees points that most others see (the reduced camera
// system is dense), and the track lengths have a heavy tail: the median near track_min, a
// mean of about 4 track_min less what track_max cuts, and some tracks of every camera.
TEST(SbagenScene, PhotoCollectionSharesPointsBetweenMostCameraPairs) {
  const Options o = small_photo();
  const Scene s = make(o);
  check_structure(o, s);
  check_truth_projections(s);
  const int m = o.cameras;
  std::vector<char> pair(static_cast<std::size_t>(m) * m, 0);
  std::vector<int> lengths;
  for (int i = 0; i < s.npoints(); ++i) {
    const std::size_t b = s.track_begin[i], e = s.track_begin[i + 1];
    lengths.push_back(static_cast<int>(e - b));
    for (std::size_t k = b; k < e; ++k)
      for (std::size_t l = k + 1; l < e; ++l) pair[s.track_cameras[k] * m + s.track_cameras[l]] = 1;
  }
  int shared = 0;
  for (int a = 0; a < m; ++a)
    for (int b = a + 1; b < m; ++b) shared += pair[a * m + b];
  EXPECT_GT(shared, 0.95 * m * (m - 1) / 2);
  std::sort(lengths.begin(), lengths.end());
  const double mean = double(s.nprojections()) / s.npoints();
  EXPECT_LE(lengths[lengths.size() / 2], 2 * o.track_min);
  EXPECT_GT(mean, 2.5 * o.track_min);
  EXPECT_LT(mean, 4.0 * o.track_min);
  EXPECT_EQ(lengths.back(), o.track_max);
}

TEST(SbagenScene, SparseAtScaleWithoutTheDenseVmask) {
  Options o;
  o.cameras = 300;
  o.points = 20000;
  o.dense_vmask_limit = 0;
  for (Trajectory t : {Trajectory::Orbit, Trajectory::Path, Trajectory::Photo}) {
    o.trajectory = t;
    const Scene s = make(o);
    EXPECT_FALSE(s.has_dense_vmask());
    EXPECT_EQ(s.npoints(), o.points);
    EXPECT_GE(s.nprojections(), 2u * o.points);
    EXPECT_LE(s.nprojections(), 10u * o.points);
  }
}

// ---- measurements ----

TEST(SbagenNoise, MeanSquaredErrorIsSigmaSquared) {
  Options o = small_orbit();
  o.points = 3000;
  o.noise = 0.7;
  const Scene s = make(o);
  double sum = 0, sum2 = 0;
  const std::size_t values = s.measurements.x.size();
  for (std::size_t k = 0; k < values; ++k) {
    const double e = s.measurements.x[k] - s.true_x[k];
    sum += e;
    sum2 += e * e;
  }
  // The sample variance of `values` normal draws has a relative spread of sqrt(2/values) (~1%).
  EXPECT_NEAR(sum2 / values, o.noise * o.noise, 0.05 * o.noise * o.noise);
  EXPECT_NEAR(sum / values, 0.0, 5 * o.noise / std::sqrt(values));
}

TEST(SbagenNoise, ZeroNoiseGivesTheExactProjections) {
  Options o = small_orbit();
  o.noise = 0;
  const Scene s = make(o);
  EXPECT_EQ(s.measurements.x, s.true_x);
}

TEST(SbagenNoise, CovariancesAreSpdAndDescribeTheNoise) {
  Options o = small_orbit();
  o.points = 3000;
  o.noise = 0.5;
  o.covariances = true;
  const Scene s = make(o);
  const std::vector<double> &C = s.measurements.covx;
  double mahalanobis = 0;
  const std::size_t N = s.nprojections();
  for (std::size_t k = 0; k < N; ++k) {
    const double *c = &C[4 * k];
    ASSERT_EQ(c[1], c[2]);
    ASSERT_GT(c[0], 0.0);
    const double det = c[0] * c[3] - c[1] * c[2];
    ASSERT_GT(det, 0.0);
    // Eigenvalues within the documented [sigma/2, 2 sigma]^2.
    const double half_tr = 0.5 * (c[0] + c[3]), disc = std::sqrt(half_tr * half_tr - det);
    ASSERT_GE(half_tr - disc, 0.25 * o.noise * o.noise * (1 - 1e-9));
    ASSERT_LE(half_tr + disc, 4.0 * o.noise * o.noise * (1 + 1e-9));
    const double ex = s.measurements.x[2 * k] - s.true_x[2 * k], ey = s.measurements.x[2 * k + 1] - s.true_x[2 * k + 1];
    mahalanobis += (c[3] * ex * ex - 2 * c[1] * ex * ey + c[0] * ey * ey) / det;
  }
  // e^T C^-1 e is chi-square with 2 degrees of freedom when e is drawn from C.
  EXPECT_NEAR(mahalanobis / N, 2.0, 0.1);
}

TEST(SbagenOutliers, FractionFlagsAndDistance) {
  Options o = small_orbit();
  o.points = 2000;
  o.outliers = 0.1;
  const Scene s = make(o);
  const std::size_t N = s.nprojections();
  EXPECT_EQ(s.noutliers(), static_cast<std::size_t>(std::llround(0.1 * N)));
  for (std::size_t k = 0; k < N; ++k) {
    const double d = std::hypot(s.measurements.x[2 * k] - s.true_x[2 * k], s.measurements.x[2 * k + 1] - s.true_x[2 * k + 1]);
    if (s.outlier[k])
      ASSERT_GE(d, std::max(5.0, 10 * o.noise));
    else
      ASSERT_LT(d, 8 * o.noise);
  }
  o.outliers = 0;
  EXPECT_EQ(make(o).noutliers(), 0u);
}

TEST(SbagenPerturbation, InitialEstimateMovesAsAsked) {
  Options o = small_orbit();
  o.kind = CameraKind::VaryingIntrinsicsDistortion;
  const Scene s = make(o);
  double rot2 = 0, pts2 = 0;
  for (int j = 0; j < s.ncameras(); ++j) {
    double Rt[9], Ri[9];
    rotation(s.true_cameras[j], Rt);
    rotation(s.initial_cameras[j], Ri);
    rot2 += std::pow(angle_between(Rt, Ri), 2);
    // The held terms keep their true values.
    EXPECT_EQ(s.initial_cameras[j].k.ar, s.true_cameras[j].k.ar);
    EXPECT_EQ(s.initial_cameras[j].k.s, s.true_cameras[j].k.s);
    for (int d = 2; d < 5; ++d) EXPECT_EQ(s.initial_cameras[j].kc[d], s.true_cameras[j].kc[d]);
    EXPECT_NE(s.initial_cameras[j].k.fu, s.true_cameras[j].k.fu);
    EXPECT_NE(s.initial_cameras[j].kc[0], s.true_cameras[j].kc[0]);
  }
  for (std::size_t k = 0; k < s.true_points.size(); ++k)
    pts2 += std::pow(s.initial_points()[k] - s.true_points[k], 2);
  // The rotation angle of a 3-axis perturbation has E[angle^2] = 3 sigma^2.
  EXPECT_NEAR(std::sqrt(rot2 / s.ncameras()), std::sqrt(3.0) * o.perturb_rotation, 0.5 * o.perturb_rotation);
  EXPECT_NEAR(std::sqrt(pts2 / s.true_points.size()), o.perturb_points, 0.1 * o.perturb_points);

  o.perturb_rotation = o.perturb_translation = o.perturb_points = o.perturb_intrinsics = 0;
  const Scene exact = make(o);
  EXPECT_EQ(exact.initial_points(), exact.true_points);
  for (int j = 0; j < exact.ncameras(); ++j) EXPECT_EQ(exact.initial_cameras[j].k.fu, exact.true_cameras[j].k.fu);
}

// ---- files ----

void expect_loaded(const eucsba::Problem &p, const Scene &s, const std::vector<Camera> &cams,
                   const std::vector<double> &xyz, const std::vector<double> &x) {
  ASSERT_EQ(p.kind, s.kind);
  ASSERT_EQ(p.cameras.size(), cams.size());
  ASSERT_EQ(p.points.npoints(), s.npoints());
  ASSERT_EQ(static_cast<std::size_t>(p.points.nprojections()), s.nprojections());
  EXPECT_EQ(p.points.vmask, sbagen::dense_vmask(s));
  for (std::size_t j = 0; j < cams.size(); ++j) {
    EXPECT_NEAR(p.cameras[j].q.w, cams[j].q.w, 1e-10);
    EXPECT_NEAR(p.cameras[j].q.x, cams[j].q.x, 1e-10);
    EXPECT_NEAR(p.cameras[j].t[2], cams[j].t[2], 1e-9 * std::fabs(cams[j].t[2]) + 1e-12);
    EXPECT_NEAR(p.cameras[j].k.fu, cams[j].k.fu, 1e-7);
    EXPECT_NEAR(p.cameras[j].k.u0, cams[j].k.u0, 1e-7);
    EXPECT_NEAR(p.cameras[j].k.ar, cams[j].k.ar, 1e-10);
    EXPECT_NEAR(p.cameras[j].kc[0], cams[j].kc[0], 1e-10);
  }
  for (std::size_t k = 0; k < xyz.size(); ++k) ASSERT_NEAR(p.points.xyz[k], xyz[k], 1e-9 * std::fabs(xyz[k]) + 1e-12);
  for (std::size_t k = 0; k < x.size(); ++k) ASSERT_NEAR(p.points.x[k], x[k], 1e-7);
  ASSERT_EQ(p.points.covx.size(), s.measurements.covx.size());
  for (std::size_t k = 0; k < s.measurements.covx.size(); ++k)
    ASSERT_NEAR(p.points.covx[k], s.measurements.covx[k], 1e-9 * std::fabs(s.measurements.covx[k]));
}

TEST(SbagenFiles, WrittenProblemsLoadBack) {
  const TempDir dir("files");
  for (CameraKind kind :
       {CameraKind::FixedIntrinsics, CameraKind::VaryingIntrinsics, CameraKind::VaryingIntrinsicsDistortion}) {
    Options o = small_orbit();
    o.kind = kind;
    o.covariances = kind == CameraKind::VaryingIntrinsics;
    o.outliers = kind == CameraKind::FixedIntrinsics ? 0.05 : 0;
    const Scene s = make(o);
    const std::string prefix = dir.file(sbagen::camera_kind_name(kind));
    std::string error;
    ASSERT_TRUE(sbagen::write_problem(s, prefix, &error)) << error;
    const sbagen::ProblemFiles f = sbagen::problem_files(prefix, s);
    EXPECT_EQ(f.cams, prefix + "-cams.txt");
    EXPECT_EQ(f.truth_pts, prefix + "-truth-pts.txt");
    EXPECT_EQ(f.calib.empty(), kind != CameraKind::FixedIntrinsics);
    EXPECT_EQ(f.outliers.empty(), o.outliers == 0);
    EXPECT_EQ(std::filesystem::exists(prefix + "-calib.txt"), kind == CameraKind::FixedIntrinsics);
    EXPECT_EQ(std::filesystem::exists(prefix + "-outliers.txt"), o.outliers > 0);

    eucsba::Problem initial, truth;
    ASSERT_TRUE(eucsba::load_problem(f.cams, f.pts, f.calib, &initial, &error)) << error;
    expect_loaded(initial, s, s.initial_cameras, s.initial_points(), s.measurements.x);
    ASSERT_TRUE(eucsba::load_problem(f.truth_cams, f.truth_pts, f.calib, &truth, &error)) << error;
    expect_loaded(truth, s, s.true_cameras, s.true_points, s.true_x);

    if (!f.outliers.empty()) {
      std::ifstream in(f.outliers);
      std::string line;
      std::size_t count = 0;
      while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#') continue;
        int i = -1, j = -1;
        ASSERT_EQ(std::sscanf(line.c_str(), "%d %d", &i, &j), 2);
        const auto b = s.track_cameras.begin();
        const auto it = std::find(b + s.track_begin[i], b + s.track_begin[i + 1], j);
        ASSERT_NE(it, b + s.track_begin[i + 1]);
        EXPECT_TRUE(s.outlier[it - b]);
        ++count;
      }
      EXPECT_EQ(count, s.noutliers());
    }
  }
}

TEST(SbagenFiles, SparseWriterMatchesTheDemoWriter) {
  const TempDir dir("sparse");
  for (bool cov : {false, true}) {
    Options o = small_path();
    o.covariances = cov;
    const Scene dense = make(o);
    o.dense_vmask_limit = 0;
    const Scene sparse = make(o);
    std::string error;
    ASSERT_TRUE(sbagen::write_problem(dense, dir.file("dense"), &error)) << error;
    ASSERT_TRUE(sbagen::write_problem(sparse, dir.file("sparse"), &error)) << error;
    for (const char *suffix : {"-pts.txt", "-truth-pts.txt", "-cams.txt"}) {
      const std::string a = slurp(dir.file("dense") + suffix), b = slurp(dir.file("sparse") + suffix);
      EXPECT_FALSE(a.empty());
      EXPECT_EQ(a, b) << suffix;
    }
  }
}

TEST(SbagenFiles, UnwritablePrefixIsAnError) {
  const Scene s = make(small_orbit());
  std::string error;
  EXPECT_FALSE(sbagen::write_problem(s, "/nonexistent-dir/for/sure/x", &error));
  EXPECT_EQ(error.rfind("/nonexistent-dir/for/sure/x-cams.txt: cannot open for writing: ", 0), 0u) << error;
}

// ---- refinement back to the truth ----

// Mean squared reprojection error at the optimum: 2 sigma^2 per projection, less the share of
// the 2N residual degrees of freedom the fit absorbs (parameters minus the 7 of the gauge).
double expected_mse(const Scene &s, double sigma) {
  const double N = static_cast<double>(s.nprojections());
  const double params = s.ncameras() * euclidean::camera_params(s.kind) + 3.0 * s.npoints() - 7;
  return 2 * sigma * sigma * (1 - params / (2 * N));
}

TEST(SbagenSolve, NoisyOrbitConvergesToTheTruthUpToTheGauge) {
  Options o = small_orbit();
  o.noise = 0.5;
  const Scene s = make(o);
  const Solution sol = solve(s);
  ASSERT_NE(sol.ret, SBA_ERROR);
  const double N = static_cast<double>(s.nprojections());
  const double mse = sol.info[1] / N, expected = expected_mse(s, o.noise);
  EXPECT_GT(sol.info[0] / N, 20 * expected) << "the start is away from the truth";
  EXPECT_NEAR(mse, expected, 0.15 * expected);

  // Gauge-free comparison with the truth, and with how far the start was.
  const Shape truth = shape(s.true_cameras, s.true_points);
  const Shape refined = shape(sol.cameras, sol.points);
  const Shape start = shape(s.initial_cameras, s.initial_points());
  const double cam_err = max_abs_diff(truth.camera_distances, refined.camera_distances);
  const double pt_err = rms_diff(truth.point_distances, refined.point_distances);
  const double rot_err = max_relative_rotation_error(s.true_cameras, sol.cameras);
  // Noise leaves an estimation error (about 1.6e-3, 0.7e-3 and 1.9e-3 rad here for a start
  // at 1.9e-2, 0.8e-2 and 5.2e-2 rad); the noise-free test below shows exact recovery.
  EXPECT_LT(cam_err, 5e-3);
  EXPECT_LT(pt_err, 3e-3);
  EXPECT_LT(rot_err, 5e-3);
  EXPECT_LT(cam_err, 0.25 * max_abs_diff(truth.camera_distances, start.camera_distances));
  EXPECT_LT(pt_err, 0.25 * rms_diff(truth.point_distances, start.point_distances));
  EXPECT_LT(rot_err, 0.25 * max_relative_rotation_error(s.true_cameras, s.initial_cameras));

  // The truth does not minimize the error of noisy data: the optimum found must fit the
  // measurements at least as well as the truth does.
  double truth_cost = 0;
  for (std::size_t k = 0; k < s.measurements.x.size(); ++k)
    truth_cost += std::pow(s.measurements.x[k] - s.true_x[k], 2);
  EXPECT_LE(sol.info[1], truth_cost);
}

TEST(SbagenSolve, NoiseFreeProblemsAreRecoveredExactly) {
  for (Options o : {small_orbit(), small_path(), small_photo()}) {
    o.noise = 0;
    o.points = 150;
    o.cameras = o.trajectory == Trajectory::Path ? 12 : 8;
    if (o.trajectory == Trajectory::Orbit) {
      o.kind = CameraKind::VaryingIntrinsicsDistortion;
      o.image_width = 1024;
      o.image_height = 768;
    }
    const Scene s = make(o);
    const Solution sol = solve(s);
    ASSERT_NE(sol.ret, SBA_ERROR);
    EXPECT_LT(sol.info[1] / s.nprojections(), 1e-12) << sbagen::trajectory_name(o.trajectory);
    const Shape truth = shape(s.true_cameras, s.true_points);
    const Shape refined = shape(sol.cameras, sol.points);
    EXPECT_LT(max_abs_diff(truth.camera_distances, refined.camera_distances), 1e-6);
    EXPECT_LT(max_abs_diff(truth.point_distances, refined.point_distances), 1e-6);
    EXPECT_LT(max_relative_rotation_error(s.true_cameras, sol.cameras), 1e-6);
    for (int j = 0; j < s.ncameras(); ++j) {  // intrinsics are free of the gauge
      EXPECT_NEAR(sol.cameras[j].k.fu, s.true_cameras[j].k.fu, 1e-4);
      EXPECT_NEAR(sol.cameras[j].kc[0], s.true_cameras[j].kc[0], 1e-6);
    }
  }
}

TEST(SbagenSolve, CovariancesWeightTheFit) {
  // With covx the optimum's weighted error e^T C^-1 e is chi-square: 2 per projection less
  // the fitted share.
  Options o = small_orbit();
  o.covariances = true;
  const Scene s = make(o);
  const Solution sol = solve(s);
  ASSERT_NE(sol.ret, SBA_ERROR);
  const double expected = expected_mse(s, 1.0);
  EXPECT_NEAR(sol.info[1] / s.nprojections(), expected, 0.15 * expected);
}

// ---- the program ----

// sbagen writes the same scenes as files.
TEST(Sbagen, WritesColmapAndBundlerFiles) {
  const TempDir dir("program");
  const std::string gen = std::string(SBAGEN_EXE) + " --cameras 6 --points 60 --quiet --out " + dir.file("g");
  ASSERT_EQ(std::system((gen + " --kind varKD --colmap " + dir.file("t") + " --colmap-binary " + dir.file("b")).c_str()),
            0);
  colmap::Model text, binary;
  std::string error;
  ASSERT_TRUE(colmap::read_model(dir.file("t"), &text, nullptr, &error)) << error;
  ASSERT_TRUE(colmap::read_model(dir.file("b"), &binary, nullptr, &error)) << error;
  refinetest::expect_same(text, binary);
  ASSERT_EQ(text.cameras.size(), 6u);
  EXPECT_EQ(text.cameras[0].model, colmap::kOpenCV);
  EXPECT_EQ(text.images[5].name, "img_0005.png");
  EXPECT_EQ(text.points[1].id, 1007u);
  const int st = std::system((gen + " --kind varKD --bundler " + dir.file("x.out") + " 2>" + dir.file("err")).c_str());
  EXPECT_EQ(WEXITSTATUS(st), 1);
  EXPECT_EQ(slurp(dir.file("err")), "sbagen: camera 0 has an aspect ratio, a skew or distortion terms beyond k1 k2, "
                                    "which Bundler cannot hold\n");
  ASSERT_EQ(std::system((gen + " --kind varK --bundler " + dir.file("g.out")).c_str()), 0);
  bundler::Bundle b;
  ASSERT_TRUE(bundler::read_bundle(dir.file("g.out"), &b, &error)) << error;
  EXPECT_EQ(b.cameras.size(), 6u);
  EXPECT_EQ(b.points.size(), 60u);
}

}  // namespace
