// SPDX-License-Identifier: BSD-3-Clause
// Camera parameters held by a mask and shared by groups of cameras (sba_ext.h: cam_fixed,
// cam_group, cam_shared), on a scene of one physical camera: twelve images whose K is the
// same lens, started with the focal length 2% long.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "cameras/euclidean.h"
#include "generator/sbagen.h"
#include "sba_ext.h"
#include "synth.h"

namespace {

using sbacameras::euclidean::CameraKind;
using sbacameras::euclidean::CameraModel;
using sbacameras::euclidean::Refinement;

constexpr double kTrueFocal = 800.0;
constexpr int kCnp = 11;  // fu u0 v0 ar s  v1 v2 v3  t1 t2 t3

struct Scene {
  sbagen::Scene scene;
  std::unique_ptr<CameraModel> model;
  std::vector<double> p0;  // cameras then points
  int m = 0, n = 0;
};

Scene make_scene(int cameras = 12, int points = 300) {
  sbagen::Options o;
  o.cameras = cameras;
  o.points = points;
  o.kind = CameraKind::VaryingIntrinsics;
  o.intrinsics_spread = 0.0;  // one lens
  o.perturb_intrinsics = 0.0;
  o.track_min = 3;
  o.track_max = 8;
  o.focal = kTrueFocal;
  o.noise = 0.5;
  o.seed = 7;
  Scene s;
  std::string error;
  EXPECT_TRUE(sbagen::generate(o, &s.scene, &error)) << error;
  std::vector<sbacameras::euclidean::Camera> cams = s.scene.initial_cameras;
  for (auto &c : cams) c.k.fu = 1.02 * kTrueFocal;
  // The model holds nothing itself: what is held is the mask's business here.
  s.model = std::make_unique<CameraModel>(CameraKind::VaryingIntrinsics, cams, s.scene.initial_points(), 0, 0);
  s.m = s.model->ncameras();
  s.n = s.model->npoints();
  s.p0 = s.model->initial_camera_params();
  s.p0.insert(s.p0.end(), s.model->initial_points().begin(), s.model->initial_points().end());
  return s;
}

struct Solved {
  int ret = 0;
  std::vector<double> p;
  double info[SBA_INFOSZ] = {};
};

// What a caller sets: the lens (fu u0 v0 ar s) shared by every camera; u0 v0 ar s held.
struct Config {
  std::vector<char> fixed = std::vector<char>{0, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0};
  bool per_camera = false;
  std::vector<int> group;  // empty: every camera in group 0
  std::vector<char> shared = std::vector<char>{1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0};
  bool share = true;
  const char *linsolver = "chol";
  const char *strategy = "sba";
  int nthreads = 1;
  int itmax = 100;
  int mcon = 0;
  bool motion_only = false;
  const char *loss = nullptr;
  int (*progress)(void *, const sba_progress *) = nullptr;
};

Solved run(const Scene &s, const Config &u) {
  Solved r;
  r.p = s.p0;
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.quiet = 1;
  ext.linsolver = u.linsolver;
  ext.strategy = u.strategy;
  ext.nthreads = u.nthreads;
  ext.loss = u.loss;
  ext.loss_scale = 1.0;
  ext.progress = u.progress;
  std::vector<int> group = u.group.empty() ? std::vector<int>(size_t(s.m), 0) : u.group;
  if (!u.fixed.empty()) {
    ext.cam_fixed = u.fixed.data();
    ext.cam_fixed_per_camera = u.per_camera;
  }
  if (u.share) {
    ext.cam_group = group.data();
    ext.cam_shared = u.shared.data();
  }
  const double opts[SBA_OPTSSZ] = {1e-3, 1e-12, 1e-12, 1e-12, 0.0};
  std::vector<char> vmask = sbagen::dense_vmask(s.scene);
  std::vector<double> x = s.scene.measurements.x;
  void *adata = sbacameras::euclidean::as_adata(*s.model);
  if (u.motion_only) {
    const auto cb = sbacameras::euclidean::expert_callbacks(CameraKind::VaryingIntrinsics, Refinement::Motion);
    r.ret = sba_mot_levmar_x_ext(s.n, s.m, u.mcon, vmask.data(), r.p.data(), kCnp, x.data(), nullptr, 2, cb.func,
                                 cb.fjac, adata, u.itmax, 0, opts, r.info, &ext);
  } else {
    const auto cb = sbacameras::euclidean::expert_callbacks(CameraKind::VaryingIntrinsics, Refinement::MotionStructure);
    r.ret = sba_motstr_levmar_x_ext(s.n, 0, s.m, u.mcon, vmask.data(), r.p.data(), kCnp, 3, x.data(), nullptr, 2,
                                    cb.func, cb.fjac, adata, u.itmax, 0, opts, r.info, &ext);
  }
  return r;
}

double focal(const Solved &r, int j) { return r.p[size_t(j) * kCnp]; }

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

TEST(CameraParams, SharedFocalLengthComesBackToTheTruth) {
  const Scene s = make_scene();
  const Solved r = run(s, Config{});
  ASSERT_GT(r.ret, 0);
  // One focal length for the lens, every camera holding the same bits.
  for (int j = 1; j < s.m; ++j) EXPECT_TRUE(same_bits(focal(r, j), focal(r, 0))) << j;
  // Started at 816, back within the noise of 800.
  EXPECT_NEAR(focal(r, 0), kTrueFocal, 1.0);
  // About the noise: 0.5 px per coordinate, two per projection.
  const double nobs = double(s.scene.nprojections());
  EXPECT_LT(std::sqrt(r.info[1] / (2.0 * nobs)), 0.55);
  // The held principal point, aspect ratio and skew are the bits they started with.
  for (int j = 0; j < s.m; ++j)
    for (int a = 1; a < 5; ++a)
      EXPECT_TRUE(same_bits(r.p[size_t(j) * kCnp + a], s.p0[size_t(j) * kCnp + a])) << j << " " << a;
}

TEST(CameraParams, WithoutSharingEachCameraGetsAFocalLengthOfItsOwn) {
  // The contrast the sharing is for: the same scene, each camera's focal length its own.
  const Scene s = make_scene();
  Config u;
  u.share = false;
  const Solved r = run(s, u);
  ASSERT_GT(r.ret, 0);
  double lo = 1e300, hi = -1e300;
  for (int j = 0; j < s.m; ++j) {
    lo = std::min(lo, focal(r, j));
    hi = std::max(hi, focal(r, j));
  }
  EXPECT_GT(hi - lo, 0.5);
}

TEST(CameraParams, EverySolverAndStrategyReachesOneMinimum) {
  const Scene s = make_scene();
  const Solved ref = run(s, Config{});
  ASSERT_GT(ref.ret, 0);
  for (const char *solver : {"chol", "sparse-chol", "iterative-schur", "ldl-amd", "ldlt", "lu", "qr"})
    for (const char *strategy : {"sba", "sba-clean-retry", "trust-region"}) {
      Config u;
      u.linsolver = solver;
      u.strategy = strategy;
      const Solved r = run(s, u);
      ASSERT_GT(r.ret, 0) << solver << " " << strategy;
      EXPECT_NEAR(r.info[1], ref.info[1], 1e-6 * ref.info[1]) << solver << " " << strategy;
      EXPECT_NEAR(focal(r, 0), focal(ref, 0), 1e-3) << solver << " " << strategy;
      for (int j = 1; j < s.m; ++j) EXPECT_TRUE(same_bits(focal(r, j), focal(r, 0)));
    }
}

TEST(CameraParams, WithARobustLossAndAProgressCallback) {
  const Scene s = make_scene();
  Config u;
  u.loss = "huber";
  u.progress = [](void *, const sba_progress *st) { return st->iteration >= 12 ? 1 : 0; };
  const Solved r = run(s, u);
  ASSERT_EQ(r.ret, 12);
  EXPECT_EQ(r.info[6], SBA_STOP_USER);
  for (int j = 1; j < s.m; ++j) EXPECT_TRUE(same_bits(focal(r, j), focal(r, 0)));
  EXPECT_LT(std::fabs(focal(r, 0) - kTrueFocal), 1.0);  // from 16
}

TEST(CameraParams, TheSameBitsForAnyThreadCount) {
  const Scene s = make_scene();
  for (const char *solver : {"chol", "sparse-chol", "iterative-schur"}) {
    Config u;
    u.linsolver = solver;
    u.nthreads = 1;
    const Solved a = run(s, u);
    u.nthreads = 2;
    const Solved b = run(s, u);
    ASSERT_GT(a.ret, 0);
    EXPECT_EQ(a.ret, b.ret) << solver;
    EXPECT_EQ(0, std::memcmp(a.p.data(), b.p.data(), a.p.size() * sizeof(double))) << solver;
  }
}

TEST(CameraParams, SeveralSharedParametersInBothStrategies) {
  // fu, u0 and v0 shared and free: three shared unknowns, which the bordering pairs with each
  // other (and, in the trust region, with their scaled copies).
  const Scene s = make_scene();
  Config u;
  u.fixed = {0, 0, 0, 1, 1, 0, 0, 0, 0, 0, 0};
  const Solved a = run(s, u);
  u.strategy = "trust-region";
  const Solved b = run(s, u);
  u.linsolver = "iterative-schur";
  const Solved c = run(s, u);
  for (const Solved *r : {&a, &b, &c}) {
    ASSERT_GT(r->ret, 0);
    for (int j = 1; j < s.m; ++j)
      for (int q = 0; q < 3; ++q)
        EXPECT_TRUE(same_bits(r->p[size_t(j) * kCnp + q], r->p[size_t(q)])) << j << " " << q;
    EXPECT_NEAR(r->info[1], a.info[1], 1e-6 * a.info[1]);
    EXPECT_NEAR(focal(*r, 0), kTrueFocal, 2.0);
  }
  // The principal point moved from where it started.
  EXPECT_NE(a.p[1], s.p0[1]);
}

TEST(CameraParams, GroupsOfTheirOwn) {
  // Two lenses: even cameras one, odd the other; a camera in no group keeps its own.
  const Scene s = make_scene();
  Config u;
  u.group.assign(size_t(s.m), 0);
  for (int j = 0; j < s.m; ++j) u.group[size_t(j)] = j == 5 ? -1 : (j % 2 ? 9 : 4);
  const Solved r = run(s, u);
  ASSERT_GT(r.ret, 0);
  for (int j = 2; j < s.m; ++j)
    if (j != 5) EXPECT_TRUE(same_bits(focal(r, j), focal(r, j % 2))) << j;
  EXPECT_FALSE(same_bits(focal(r, 0), focal(r, 1)));
  EXPECT_FALSE(same_bits(focal(r, 5), focal(r, 1)));
  EXPECT_NEAR(focal(r, 0), kTrueFocal, 2.0);
  EXPECT_NEAR(focal(r, 1), kTrueFocal, 2.0);
}

TEST(CameraParams, HeldByCameraAreTheBitsTheyStartedWith) {
  // Camera 3's pose and every camera's skew held, the skew of camera 2 a negative zero.
  Scene s = make_scene();
  s.p0[2 * kCnp + 4] = -0.0;
  Config u;
  u.share = false;
  u.per_camera = true;
  u.fixed.assign(size_t(s.m) * kCnp, 0);
  for (int j = 0; j < s.m; ++j) u.fixed[size_t(j) * kCnp + 4] = 1;
  for (int a = 5; a < kCnp; ++a) u.fixed[3 * kCnp + a] = 1;
  const Solved r = run(s, u);
  ASSERT_GT(r.ret, 0);
  for (int a = 5; a < kCnp; ++a) EXPECT_TRUE(same_bits(r.p[3 * kCnp + a], s.p0[3 * kCnp + a])) << a;
  for (int j = 0; j < s.m; ++j) EXPECT_TRUE(same_bits(r.p[size_t(j) * kCnp + 4], s.p0[size_t(j) * kCnp + 4]));
  EXPECT_TRUE(std::signbit(r.p[2 * kCnp + 4]));
  // Camera 4's pose moved (it was free).
  EXPECT_FALSE(same_bits(r.p[4 * kCnp + 8], s.p0[4 * kCnp + 8]));
}

TEST(CameraParams, MotionOnlyWithASharedLens) {
  const Scene s = make_scene();
  Config u;
  u.motion_only = true;
  const Solved r = run(s, u);
  ASSERT_GT(r.ret, 0);
  for (int j = 1; j < s.m; ++j) EXPECT_TRUE(same_bits(focal(r, j), focal(r, 0)));
  // The points are the perturbed ones and held: the lens absorbs some of that, but moves
  // towards the truth from 816.
  EXPECT_LT(std::fabs(focal(r, 0) - kTrueFocal), 16.0);
}

TEST(CameraParams, StartsFromTheFirstCameraOfAGroup) {
  Scene s = make_scene();
  for (int j = 1; j < s.m; ++j) s.p0[size_t(j) * kCnp] = 700.0 + j;  // only camera 0 says 816
  Config u;
  u.itmax = 1;
  const Solved r = run(s, u);
  ASSERT_GE(r.ret, 0);
  for (int j = 1; j < s.m; ++j) EXPECT_TRUE(same_bits(focal(r, j), focal(r, 0)));
  EXPECT_NEAR(focal(r, 0), 816.0, 16.0);
}

TEST(CameraParams, BadArguments) {
  const Scene s = make_scene(6, 80);
  {
    Config u;
    u.group.assign(size_t(s.m), 0);
    u.group[2] = s.m;  // beyond m - 1
    EXPECT_EQ(run(s, u).ret, SBA_ERROR);
    u.group[2] = -2;
    EXPECT_EQ(run(s, u).ret, SBA_ERROR);
  }
  {
    Config u;
    u.mcon = 1;  // camera 0 held whole, but in group 0
    EXPECT_EQ(run(s, u).ret, SBA_ERROR);
  }
  {
    // fu shared but held in camera 1 only.
    Config u;
    u.per_camera = true;
    u.fixed.assign(size_t(s.m) * kCnp, 0);
    u.fixed[1 * kCnp + 0] = 1;
    const Solved r = run(s, u);
    EXPECT_EQ(r.ret, SBA_ERROR);
    EXPECT_EQ(r.info[6], SBA_STOP_NONE);
  }
  {
    // Held in every camera of the group: fine, and fu stays 816.
    Config u;
    u.fixed[0] = 1;
    const Solved r = run(s, u);
    ASSERT_GT(r.ret, 0);
    EXPECT_EQ(focal(r, 3), 1.02 * kTrueFocal);
  }
}

}  // namespace

namespace {

TEST(CameraParams, CovarianceOfASharedLens) {
  const Scene s = make_scene();
  const Config u;
  const Solved r = run(s, u);
  ASSERT_GT(r.ret, 0);
  std::vector<double> p = r.p;
  std::vector<int> group(size_t(s.m), 0);
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.quiet = 1;
  ext.cam_fixed = u.fixed.data();
  ext.cam_group = group.data();
  ext.cam_shared = u.shared.data();
  sba_covariance_request req;
  sba_covariance_request_init(&req);
  const int cams[2] = {3, 7};
  std::vector<double> camcov(2 * kCnp * kCnp);
  req.ncams = 2;
  req.cams = cams;
  req.camcov = camcov.data();
  const int pts[1] = {5};
  std::vector<double> ptcov(9);
  req.npts = 1;
  req.pts = pts;
  req.ptcov = ptcov.data();
  std::vector<char> vmask = sbagen::dense_vmask(s.scene);
  std::vector<double> x = s.scene.measurements.x;
  const auto cb = sbacameras::euclidean::expert_callbacks(CameraKind::VaryingIntrinsics, Refinement::MotionStructure);
  ASSERT_EQ(0, sba_motstr_covariance_x(s.n, 0, s.m, 0, vmask.data(), p.data(), kCnp, 3, x.data(), nullptr, 2,
                                       cb.func, cb.fjac, sbacameras::euclidean::as_adata(*s.model), &req, &ext));
  // The unknowns: 6 pose parameters per camera, one focal length, 3 per point; the gauge
  // (a similarity: 7 directions) is left free.
  EXPECT_EQ(req.nfree, s.m * 6 + 1 + s.n * 3);
  EXPECT_EQ(req.rank, req.nfree - 7);
  // The lens's variance is one number, the same in both cameras' blocks, and positive.
  EXPECT_GT(camcov[0], 0.0);
  EXPECT_TRUE(same_bits(camcov[0], camcov[size_t(kCnp * kCnp)]));
  // The held parameters have none.
  for (int q = 0; q < 2; ++q)
    for (int a = 1; a < 5; ++a)
      for (int b = 0; b < kCnp; ++b) {
        EXPECT_EQ(camcov[size_t(q * kCnp * kCnp + a * kCnp + b)], 0.0);
        EXPECT_EQ(camcov[size_t(q * kCnp * kCnp + b * kCnp + a)], 0.0);
      }
  EXPECT_GT(ptcov[0], 0.0);
}

}  // namespace

namespace {

// Every copy of a shared parameter holds the same bits on return, whatever solves the step
// and whatever damps it: the trust region solves in scaled variables, one scale per camera,
// and a step mapped back through each copy's own scale is not exact.
TEST(CameraParams, SharedCopiesEndWithTheSameBitsForEverySolverAndStrategy) {
  const Scene s = make_scene(8, 150);
  for (const char *solver : {"chol", "chol-lapack", "ldlt", "bk", "lu", "qr", "qrnoq", "svd", "cg", "ldl-amd",
                             "sparse-chol", "iterative-schur"})
    for (const char *strategy : {"sba", "sba-clean-retry", "trust-region"}) {
      Config u;
      u.fixed = {0, 0, 0, 1, 1, 0, 0, 0, 0, 0, 0};
      u.linsolver = solver;
      u.strategy = strategy;
      u.itmax = 30;
      const Solved r = run(s, u);
      ASSERT_GT(r.ret, 0) << solver << " " << strategy;
      for (int j = 1; j < s.m; ++j)
        for (int q = 0; q < 3; ++q)
          EXPECT_TRUE(same_bits(r.p[size_t(j) * kCnp + q], r.p[size_t(q)]))
              << solver << " " << strategy << " camera " << j << " parameter " << q;
    }
  // The motion-only driver, and two threads giving the first's bits.
  for (const char *strategy : {"sba", "sba-clean-retry", "trust-region"})
    for (bool motion_only : {true, false}) {
      Config u;
      u.fixed = {0, 0, 0, 1, 1, 0, 0, 0, 0, 0, 0};
      u.strategy = strategy;
      u.motion_only = motion_only;
      u.itmax = 30;
      const Solved one = run(s, u);
      u.nthreads = 2;
      const Solved two = run(s, u);
      ASSERT_GT(one.ret, 0) << strategy << " " << motion_only;
      for (int j = 1; j < s.m; ++j)
        for (int q = 0; q < 3; ++q) EXPECT_TRUE(same_bits(one.p[size_t(j) * kCnp + q], one.p[size_t(q)]));
      EXPECT_TRUE(one.p == two.p) << strategy << " " << motion_only;
    }
}

}  // namespace

namespace {

// The synthetic scene of synth.h (cnp 6: rotation, translation) through the C API with held
// and shared parameters, the messages of the call collected.
struct SynthCall {
  std::vector<char> fixed;  // cnp flags (empty: none)
  std::vector<int> group;   // empty: none
  std::vector<char> shared;  // empty: none
  bool motion_only = false;
  int itmax = 50;
};

struct SynthResult {
  int ret = 0;
  std::vector<double> p;
  double info[SBA_INFOSZ] = {};
  std::string log;
};

SynthResult run_synth(synth::Problem &pb, const std::vector<double> &p0, const SynthCall &c) {
  SynthResult r;
  r.p = p0;
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.log = [](void *ctx, int, const char *msg) { *static_cast<std::string *>(ctx) += msg; };
  ext.log_ctx = &r.log;
  if (!c.fixed.empty()) ext.cam_fixed = c.fixed.data();
  if (!c.group.empty()) ext.cam_group = c.group.data();
  if (!c.shared.empty()) ext.cam_shared = c.shared.data();
  if (c.motion_only) {
    pb.fixed_points = pb.truth.data() + size_t(pb.m) * synth::kCnp;
    r.ret = sba_mot_levmar_x_ext(pb.n, pb.m, 0, pb.vmask.data(), r.p.data(), synth::kCnp, pb.x.data(), nullptr,
                                 synth::kMnp, synth::func_mot, synth::fjac_mot, &pb, c.itmax, 0, nullptr, r.info,
                                 &ext);
  } else {
    r.ret = sba_motstr_levmar_x_ext(pb.n, 0, pb.m, 0, pb.vmask.data(), r.p.data(), synth::kCnp, synth::kPnp,
                                    pb.x.data(), nullptr, synth::kMnp, synth::func_motstr, synth::fjac_motstr, &pb,
                                    c.itmax, 0, nullptr, r.info, &ext);
  }
  return r;
}

bool same_vector(const std::vector<double> &a, const std::vector<double> &b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

TEST(CameraParams, HeldParametersAreNotCountedAsUnknowns) {
  // One camera, two points held (motion only): 4 measurements, 6 camera parameters of which
  // 5 are held. One unknown.
  synth::Problem pb = synth::make(2, 1, 0.0, 0.05, 21, 1.0);
  std::vector<double> p0 = pb.truth;
  p0[5] += 0.1;
  SynthCall c;
  c.motion_only = true;
  c.fixed = {1, 1, 1, 1, 1, 0};
  const SynthResult r = run_synth(pb, p0, c);
  ASSERT_GE(r.ret, 1) << r.log;
  for (int a = 0; a < 5; ++a) EXPECT_TRUE(same_bits(r.p[size_t(a)], p0[size_t(a)]));
  EXPECT_NEAR(r.p[5], pb.truth[5], 1e-9);
}

TEST(CameraParams, ASharedParameterIsCountedOnce) {
  // One point seen by three cameras (6 measurements) whose rotations are held and whose
  // translations are shared: 3 unknowns, where three cameras of their own would have 9.
  synth::Problem pb = synth::make(1, 3, 0.0, 0.0, 22, 1.0);
  SynthCall c;
  c.motion_only = true;
  c.fixed = {1, 1, 1, 0, 0, 0};
  c.group = {0, 0, 0};
  c.shared = {0, 0, 0, 1, 1, 1};
  const SynthResult r = run_synth(pb, pb.p0, c);
  EXPECT_GE(r.ret, 0) << r.log;
  EXPECT_EQ(r.log.find("fewer measurements"), std::string::npos) << r.log;
  // Without the sharing the same call has more unknowns than measurements.
  c.group.clear();
  c.shared.clear();
  const SynthResult own = run_synth(pb, pb.p0, c);
  EXPECT_EQ(own.ret, SBA_ERROR);
  EXPECT_NE(own.log.find("fewer measurements (6) than free parameters (9)"), std::string::npos) << own.log;
}

TEST(CameraParams, EveryParameterHeldAndSharedSolvesThePointsAlone) {
  // Every camera parameter held, all in one shared group: the points are the only unknowns.
  // The solver no one named (auto) has no camera system to choose for; the solve is the one
  // with every parameter held and nothing shared.
  synth::Problem pb = synth::make(30, 4, 0.5, 0.05, 23);
  SynthCall c;
  c.fixed = {1, 1, 1, 1, 1, 1};
  const SynthResult held = run_synth(pb, pb.p0, c);
  ASSERT_GE(held.ret, 1) << held.log;
  c.group = {0, 0, 0, 0};
  c.shared = {1, 1, 1, 1, 1, 1};
  std::vector<double> p0 = pb.p0;
  for (int j = 1; j < 4; ++j)  // one value per shared parameter
    std::copy(p0.begin(), p0.begin() + 6, p0.begin() + 6 * j);
  const SynthResult r = run_synth(pb, p0, c);
  ASSERT_GE(r.ret, 1) << r.log;
  for (size_t a = 0; a < 24; ++a) EXPECT_TRUE(same_bits(r.p[a], p0[a])) << a;
  EXPECT_LT(r.info[1], r.info[0]);
}

TEST(CameraParams, SharedWithoutGroupsIsABadArgument) {
  synth::Problem pb = synth::make(20, 4, 0.5, 0.05, 23);
  SynthCall c;
  c.shared = {1, 0, 0, 0, 0, 0};
  const SynthResult r = run_synth(pb, pb.p0, c);
  EXPECT_EQ(r.ret, SBA_ERROR);
  EXPECT_NE(r.log.find("cam_shared is given but cam_group is NULL"), std::string::npos) << r.log;
  EXPECT_TRUE(same_vector(r.p, pb.p0));
}

TEST(CameraParams, AHeldSharedParameterWithUnequalValuesIsABadArgument) {
  synth::Problem pb = synth::make(20, 4, 0.5, 0.05, 24);
  std::vector<double> p0 = pb.p0;
  for (int j = 0; j < pb.m; ++j) p0[size_t(j) * synth::kCnp + 5] = 6.0;  // tz: one value for all
  p0[2 * synth::kCnp + 5] = 6.5;
  SynthCall c;
  c.fixed = {0, 0, 0, 0, 0, 1};
  c.group = {-1, 3, 3, 3};
  c.shared = {0, 0, 0, 0, 0, 1};
  const SynthResult r = run_synth(pb, p0, c);
  EXPECT_EQ(r.ret, SBA_ERROR);
  EXPECT_NE(r.log.find("parameter 5 is shared by cameras 1 and 2 (group 3) and held, but its values differ: 6 "
                       "and 6.5"),
            std::string::npos)
      << r.log;
  EXPECT_TRUE(same_vector(r.p, p0));
  // Camera 0 is in no group: its value may differ.
  p0[2 * synth::kCnp + 5] = 6.0;
  p0[0 * synth::kCnp + 5] = 7.0;
  const SynthResult ok = run_synth(pb, p0, c);
  EXPECT_GT(ok.ret, 0) << ok.log;
  for (int j = 0; j < pb.m; ++j) EXPECT_TRUE(same_bits(ok.p[size_t(j) * synth::kCnp + 5], p0[size_t(j) * synth::kCnp + 5]));
}

// Groups rewrite the copies of a shared parameter with their first camera's value when the
// solve starts; a call that fails before any step, or that only checks the Jacobian, must
// hand p back as it was given.
TEST(CameraParams, PIsGivenBackAsItWasWhenNothingWasSolved) {
  synth::Problem pb = synth::make(20, 4, 0.5, 0.05, 25);
  SynthCall c;
  c.group = {0, 0, 0, 0};
  c.shared = {1, 0, 0, 0, 0, 0};
  ASSERT_FALSE(same_bits(pb.p0[0], pb.p0[synth::kCnp]));
  // The Jacobian check.
  c.itmax = 0;
  const SynthResult check = run_synth(pb, pb.p0, c);
  EXPECT_EQ(check.ret, 0) << check.log;
  EXPECT_TRUE(same_vector(check.p, pb.p0));
  // f is not finite at the initial estimate: point 0 at the origin, in the focal plane of a
  // camera that sees it (its depth tz is 0).
  std::vector<double> p0 = pb.p0;
  int j = 0;
  while (!pb.vmask[size_t(j)]) ++j;
  p0[size_t(j) * synth::kCnp + 5] = 0.0;
  for (int q = 0; q < 3; ++q) p0[size_t(pb.m) * synth::kCnp + q] = 0.0;
  c.itmax = 50;
  const SynthResult failed = run_synth(pb, p0, c);
  EXPECT_EQ(failed.ret, SBA_ERROR) << failed.log;
  EXPECT_EQ(failed.info[6], SBA_STOP_NONFINITE);
  EXPECT_TRUE(same_vector(failed.p, p0));
  // A solve that iterates ties them.
  const SynthResult solved = run_synth(pb, pb.p0, c);
  ASSERT_GT(solved.ret, 0) << solved.log;
  for (int k = 1; k < pb.m; ++k) EXPECT_TRUE(same_bits(solved.p[size_t(k) * synth::kCnp], solved.p[0]));
}

}  // namespace

namespace {

// A rig of three cameras on a platform that moved through `frames` positions, as COLMAP 4's
// rigs and frames describe it: an image's parameters are its camera's focal length, its
// frame's pose (rig from world) and its camera's pose in the rig (sensor from rig), cnp 13,
// and x = f pi(R_s (R_f X + t_f) + t_s) + c. Three groupings over different columns of the
// same images, at once: the focal length by camera, the frame pose by frame, the sensor pose
// by camera (the first camera's the rig's origin, held at the identity).
constexpr int kRigCnp = 13, kSensors = 3;

struct RigScene {
  int frames = 0, m = 0, n = 0;
  std::vector<double> truth, p0, x;
  std::vector<char> vmask;
  std::vector<int> group;  // cam_param_group
  std::vector<char> held;  // cam_fixed per camera
};

void rig_project(const double *a, const double *X, double *x) {
  const synth::Rot rf = synth::rotation(a + 1), rs = synth::rotation(a + 7);
  double Xr[3], Xc[3];
  for (int r = 0; r < 3; ++r) Xr[r] = rf.R[r * 3] * X[0] + rf.R[r * 3 + 1] * X[1] + rf.R[r * 3 + 2] * X[2] + a[4 + r];
  for (int r = 0; r < 3; ++r) Xc[r] = rs.R[r * 3] * Xr[0] + rs.R[r * 3 + 1] * Xr[1] + rs.R[r * 3 + 2] * Xr[2] + a[10 + r];
  x[0] = a[0] * Xc[0] / Xc[2] + 320.0;
  x[1] = a[0] * Xc[1] / Xc[2] + 240.0;
}

void rig_func(double *p, sba_crsm *idx, int *, int *, double *hx, void *) {
  const int m = idx->nc;
  for (int i = 0; i < idx->nr; ++i)
    for (int k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k)
      rig_project(p + idx->colidx[k] * kRigCnp, p + m * kRigCnp + i * 3, hx + idx->val[k] * 2);
}

RigScene make_rig(int frames, int points, unsigned seed) {
  RigScene s;
  s.frames = frames;
  s.m = frames * kSensors;
  s.n = points;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0), U01(0.0, 1.0);
  std::normal_distribution<double> N(0.0, 1.0);
  const double focal[kSensors] = {800.0, 760.0, 840.0};
  // Sensor poses: the first the identity, the others turned and set apart along x.
  const double sensor[kSensors][6] = {{0, 0, 0, 0, 0, 0}, {0, 0.25, 0, -0.4, 0, 0}, {0, -0.25, 0, 0.4, 0, 0}};
  s.truth.resize(size_t(s.m) * kRigCnp + size_t(points) * 3);
  for (int f = 0; f < frames; ++f)
    for (int c = 0; c < kSensors; ++c) {
      double *a = s.truth.data() + size_t(f * kSensors + c) * kRigCnp;
      a[0] = focal[c];
      const double frame[6] = {0.05 * std::sin(f), -0.5 + 1.0 * f / std::max(frames - 1, 1), 0.03 * std::cos(f),
                               0.1 * std::sin(2.0 * f), 0.05 * std::cos(f), 6.0};
      for (int q = 0; q < 6; ++q) a[1 + q] = frame[q];
      for (int q = 0; q < 6; ++q) a[7 + q] = sensor[c][q];
    }
  for (int i = 0; i < points; ++i)
    for (int q = 0; q < 3; ++q) s.truth[size_t(s.m) * kRigCnp + i * 3 + q] = 1.5 * U(rng);
  // Each point seen by the cameras of a few frames.
  s.vmask.assign(size_t(points) * s.m, 0);
  for (int i = 0; i < points; ++i) {
    const int f0 = int(U01(rng) * frames) % frames, len = 2 + int(U01(rng) * 3);
    for (int f = f0; f < std::min(frames, f0 + len); ++f)
      for (int c = 0; c < kSensors; ++c)
        if (c == 0 || U01(rng) < 0.8) s.vmask[size_t(i) * s.m + f * kSensors + c] = 1;
  }
  for (int i = 0; i < points; ++i) {
    int seen = 0;
    for (int j = 0; j < s.m; ++j) seen += s.vmask[size_t(i) * s.m + j];
    for (int j = 0; seen < 2 && j < s.m; ++j)
      if (!s.vmask[size_t(i) * s.m + j]) s.vmask[size_t(i) * s.m + j] = 1, ++seen;
    for (int j = 0; j < s.m; ++j)
      if (s.vmask[size_t(i) * s.m + j]) {
        double xy[2];
        rig_project(s.truth.data() + size_t(j) * kRigCnp, s.truth.data() + size_t(s.m) * kRigCnp + i * 3, xy);
        s.x.push_back(xy[0] + 0.3 * N(rng));
        s.x.push_back(xy[1] + 0.3 * N(rng));
      }
  }
  // The start: every copy of a shared value the same, the focal lengths 3% long, the frames
  // and the rig's other cameras moved.
  s.p0 = s.truth;
  double dsensor[kSensors][6] = {};
  for (int c = 1; c < kSensors; ++c)
    for (int q = 0; q < 6; ++q) dsensor[c][q] = (q < 3 ? 0.01 : 0.03) * U(rng);
  for (int f = 0; f < frames; ++f) {
    double dframe[6];
    for (int q = 0; q < 6; ++q) dframe[q] = (q < 3 ? 0.01 : 0.05) * U(rng);
    for (int c = 0; c < kSensors; ++c) {
      double *a = s.p0.data() + size_t(f * kSensors + c) * kRigCnp;
      a[0] *= 1.03;
      for (int q = 0; q < 6; ++q) a[1 + q] += dframe[q];
      for (int q = 0; q < 6; ++q) a[7 + q] += dsensor[c][q];
    }
  }
  for (int i = 0; i < points; ++i)
    for (int q = 0; q < 3; ++q) s.p0[size_t(s.m) * kRigCnp + i * 3 + q] += 0.02 * U(rng);
  s.group.assign(size_t(s.m) * kRigCnp, -1);
  s.held.assign(size_t(s.m) * kRigCnp, 0);
  for (int f = 0; f < frames; ++f)
    for (int c = 0; c < kSensors; ++c) {
      const size_t j = size_t(f * kSensors + c);
      s.group[j * kRigCnp] = c;
      for (int q = 1; q < 7; ++q) s.group[j * kRigCnp + q] = f;
      for (int q = 7; q < 13; ++q) s.group[j * kRigCnp + q] = c;
      if (c == 0)
        for (int q = 7; q < 13; ++q) s.held[j * kRigCnp + q] = 1;
    }
  return s;
}

struct RigRun {
  const char *solver = "chol";
  const char *strategy = "sba";
  int nthreads = 1;
  bool share = true;
  bool converged = false;  // run to a relative cost change of 1e-14 (the trust region's eps4)
};

SynthResult run_rig(RigScene &s, const RigRun &r) {
  SynthResult out;
  out.p = s.p0;
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.log = [](void *ctx, int, const char *msg) { *static_cast<std::string *>(ctx) += msg; };
  ext.log_ctx = &out.log;
  ext.linsolver = r.solver;
  ext.strategy = r.strategy;
  ext.nthreads = r.nthreads;
  ext.cam_fixed = s.held.data();
  ext.cam_fixed_per_camera = 1;
  if (r.share) ext.cam_param_group = s.group.data();
  const double opts[SBA_OPTSSZ] = {1e-3, r.converged ? 1e-30 : 1e-12, r.converged ? 1e-30 : 1e-12, 1e-12,
                                   r.converged ? 1e-14 : 0.0};
  out.ret = sba_motstr_levmar_x_ext(s.n, 0, s.m, 0, s.vmask.data(), out.p.data(), kRigCnp, 3, s.x.data(), nullptr, 2,
                                    rig_func, nullptr, &s, r.converged ? 1000 : 100, 0, opts, out.info, &ext);
  return out;
}

// Every image's shared columns hold its group's first image's bits.
void expect_rig_copies_equal(const RigScene &s, const std::vector<double> &p, const std::string &what) {
  for (int j = 0; j < s.m; ++j)
    for (int q = 0; q < kRigCnp; ++q) {
      const int g = s.group[size_t(j) * kRigCnp + q];
      int first = 0;
      while (s.group[size_t(first) * kRigCnp + q] != g) ++first;
      EXPECT_TRUE(same_bits(p[size_t(j) * kRigCnp + q], p[size_t(first) * kRigCnp + q]))
          << what << ": image " << j << " parameter " << q;
    }
}

TEST(CameraParamGroups, ARigIsRefinedAsOneRig) {
  RigScene s = make_rig(10, 150, 31);
  const SynthResult r = run_rig(s, RigRun{});
  // sba's stop 4 fires at the rounding level of the cost, where the kernels' roundings part
  // ways (27 to 38 iterations seen), short of itmax.
  ASSERT_GT(r.ret, 0) << r.log;
  EXPECT_LT(r.ret, 100);
  EXPECT_EQ(r.info[6], SBA_STOP_REDUCTION);
  expect_rig_copies_equal(s, r.p, "chol");
  // At the noise (0.3 px, 0.09 px^2 per coordinate), from 49 px^2: the minimum, which a run to
  // a relative cost change of 1e-14 gives, and the stop within 3e-5 of it (1.1e-5 seen).
  RigRun converged;
  converged.strategy = "trust-region";
  converged.converged = true;
  const SynthResult min = run_rig(s, converged);
  ASSERT_GT(min.ret, 0) << min.log;
  EXPECT_NEAR(min.info[1], 146.2337833, 1e-9 * 146.2);
  EXPECT_NEAR(r.info[0], 102220.9156, 1e-3);
  EXPECT_GE(r.info[1], min.info[1] * (1 - 1e-9));
  EXPECT_LE(r.info[1], min.info[1] * (1 + 3e-5));
  EXPECT_EQ(s.x.size(), 2074u);
  // The focal lengths come back from 3% long.
  for (int c = 0; c < kSensors; ++c) EXPECT_NEAR(r.p[size_t(c) * kRigCnp], s.truth[size_t(c) * kRigCnp], 0.6) << c;
  // The first camera's pose in the rig is the identity it was held at.
  for (int q = 7; q < 13; ++q) EXPECT_EQ(r.p[size_t(q)], 0.0);
  // Without the groupings each image moves on its own: the rig comes apart.
  const SynthResult own = run_rig(s, RigRun{"chol", "sba", 1, false});
  ASSERT_GT(own.ret, 0) << own.log;
  EXPECT_FALSE(same_bits(own.p[size_t(kSensors + 1) * kRigCnp + 10], own.p[size_t(2 * kSensors + 1) * kRigCnp + 10]));
  EXPECT_LT(own.info[1], r.info[1]);  // more freedom, a lower error
}

// What sba_motstr_covariance_x gives for the rig at p: two cameras' blocks, a point's.
struct RigCovariance {
  int ret = 0, rank = 0, nfree = 0;
  double sigma2 = 0;
  std::vector<double> camcov = std::vector<double>(2 * kRigCnp * kRigCnp), ptcov = std::vector<double>(9);
};

RigCovariance rig_covariance(RigScene &s, std::vector<double> &p) {
  RigCovariance c;
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.quiet = 1;
  ext.cam_fixed = s.held.data();
  ext.cam_fixed_per_camera = 1;
  ext.cam_param_group = s.group.data();
  sba_covariance_request req;
  sba_covariance_request_init(&req);
  const int cams[2] = {4, 7}, pts[1] = {5};
  req.ncams = 2;
  req.cams = cams;
  req.camcov = c.camcov.data();
  req.npts = 1;
  req.pts = pts;
  req.ptcov = c.ptcov.data();
  c.ret = sba_motstr_covariance_x(s.n, 0, s.m, 0, s.vmask.data(), p.data(), kRigCnp, 3, s.x.data(), nullptr, 2,
                                  rig_func, nullptr, &s, &req, &ext);
  c.rank = req.rank;
  c.nfree = req.nfree;
  c.sigma2 = req.sigma2;
  return c;
}

TEST(CameraParamGroups, CovarianceOfARig) {
  RigScene s = make_rig(10, 150, 31);
  const SynthResult r = run_rig(s, RigRun{});
  ASSERT_GT(r.ret, 0) << r.log;
  std::vector<double> p = r.p;
  const RigCovariance c = rig_covariance(s, p);  // frame 1's second camera, frame 2's second
  ASSERT_EQ(c.ret, 0);
  // The unknowns: 10 frame poses, 2 sensor poses and 3 focal lengths, 3 per point; the gauge
  // (a similarity: 7 directions) is left free.
  EXPECT_EQ(c.nfree, 10 * 6 + 2 * 6 + 3 + 150 * 3);
  EXPECT_EQ(c.rank, c.nfree - 7);
  // The second camera's focal length and pose in the rig are one unknown in both images: the
  // same variances; the frames' poses are not.
  const std::vector<double> &camcov = c.camcov;
  const int cc = kRigCnp * kRigCnp;
  EXPECT_GT(camcov[0], 0.0);
  EXPECT_TRUE(same_bits(camcov[0], camcov[size_t(cc)]));
  for (int q = 7; q < 13; ++q) EXPECT_TRUE(same_bits(camcov[size_t(q * kRigCnp + q)], camcov[size_t(cc + q * kRigCnp + q)]));
  EXPECT_FALSE(same_bits(camcov[size_t(4 * kRigCnp + 4)], camcov[size_t(cc + 4 * kRigCnp + 4)]));
}

// At a p whose shared copies differ, the covariance is taken where a solve would start: every
// copy at its first camera's value. Taken at the copies as given, the Jacobian would not be
// the one of a rig (each image's own values in its own projections), nor its rank.
TEST(CameraParamGroups, CovarianceTakesEachSharedParameterAtItsFirstCamera) {
  RigScene s = make_rig(10, 150, 31);
  const SynthResult r = run_rig(s, RigRun{});
  ASSERT_GT(r.ret, 0) << r.log;
  std::vector<double> tied = r.p;
  const RigCovariance want = rig_covariance(s, tied);
  ASSERT_EQ(want.ret, 0);
  // Every copy but its group's first moved (the held ones stay, with one value in all).
  std::vector<double> apart = r.p;
  for (int j = 0; j < s.m; ++j)
    for (int q = 0; q < kRigCnp; ++q) {
      const size_t k = size_t(j) * kRigCnp + q;
      int first = 0;
      while (s.group[size_t(first) * kRigCnp + q] != s.group[k]) ++first;
      if (first < j && !s.held[k]) apart[k] += q == 0 ? 5.0 : 0.01 * (1 + q % 3);
    }
  const std::vector<double> given = apart;
  const RigCovariance got = rig_covariance(s, apart);
  ASSERT_EQ(got.ret, 0);
  EXPECT_TRUE(same_vector(apart, given));  // p is the caller's, left as given
  EXPECT_EQ(got.nfree, want.nfree);
  EXPECT_EQ(got.rank, want.rank);
  EXPECT_TRUE(same_bits(got.sigma2, want.sigma2));
  EXPECT_TRUE(same_vector(got.camcov, want.camcov));
  EXPECT_TRUE(same_vector(got.ptcov, want.ptcov));
}

// Each solver and strategy reaches the rig's minimum, whose error a run to a relative cost
// change of 1e-14 gives (the default runs stop at eps4 = 0 or the trust region's 1e-6, along
// directions the BLAS's rounding decides: within 2e-6 of it).
TEST(CameraParamGroups, EverySolverStrategyAndThreadCountKeepsTheRig) {
  RigScene s = make_rig(6, 80, 32);
  RigRun converged;
  converged.strategy = "trust-region";
  converged.converged = true;
  const SynthResult ref = run_rig(s, converged);
  ASSERT_GT(ref.ret, 0) << ref.log;
  EXPECT_NEAR(ref.info[1], 74.26332132, 1e-9 * 74.26);
  for (const char *solver : {"chol", "chol-lapack", "ldlt", "bk", "lu", "qr", "qrnoq", "svd", "cg", "ldl-amd",
                             "sparse-chol", "iterative-schur"})
    for (const char *strategy : {"sba", "sba-clean-retry", "trust-region"}) {
      const std::string what = std::string(solver) + " " + strategy;
      const SynthResult one = run_rig(s, RigRun{solver, strategy, 1, true});
      ASSERT_GT(one.ret, 0) << what << ": " << one.log;
      expect_rig_copies_equal(s, one.p, what);
      // One minimum; the trust region stops at its relative cost tolerance.
      EXPECT_NEAR(one.info[1], ref.info[1], 2e-6 * ref.info[1]) << what;
      const SynthResult two = run_rig(s, RigRun{solver, strategy, 2, true});
      EXPECT_TRUE(one.p == two.p) << what << ": 1 and 2 threads";
    }
}

TEST(CameraParamGroups, BadArguments) {
  RigScene s = make_rig(3, 30, 33);
  {
    // Together with cam_group.
    SynthResult out;
    out.p = s.p0;
    std::vector<int> cam_group(size_t(s.m), 0);
    std::vector<char> shared(kRigCnp, 1);
    sba_ext_options ext;
    sba_ext_options_init(&ext);
    ext.log = [](void *ctx, int, const char *msg) { *static_cast<std::string *>(ctx) += msg; };
    ext.log_ctx = &out.log;
    ext.cam_param_group = s.group.data();
    ext.cam_group = cam_group.data();
    ext.cam_shared = shared.data();
    out.ret = sba_motstr_levmar_x_ext(s.n, 0, s.m, 0, s.vmask.data(), out.p.data(), kRigCnp, 3, s.x.data(), nullptr,
                                      2, rig_func, nullptr, &s, 10, 0, nullptr, out.info, &ext);
    EXPECT_EQ(out.ret, SBA_ERROR);
    EXPECT_NE(out.log.find("cam_param_group and cam_group/cam_shared are given together"), std::string::npos)
        << out.log;
  }
  {
    RigScene t = s;
    t.group[5 * kRigCnp + 3] = -2;
    const SynthResult out = run_rig(t, RigRun{});
    EXPECT_EQ(out.ret, SBA_ERROR);
    EXPECT_NE(out.log.find("cam_param_group[68] = -2 is neither -1 nor a group number >= 0"), std::string::npos)
        << out.log;
  }
  {
    // The rig's origin held in one of its images only.
    RigScene t = s;
    t.held[size_t(kSensors) * kRigCnp + 8] = 0;
    const SynthResult out = run_rig(t, RigRun{});
    EXPECT_EQ(out.ret, SBA_ERROR);
    EXPECT_NE(out.log.find("parameter 8 is shared by cameras 0 and 3 (cam_param_group 0) but held (cam_fixed) in "
                           "only one of them"),
              std::string::npos)
        << out.log;
    EXPECT_TRUE(out.p == s.p0);
  }
}

}  // namespace
