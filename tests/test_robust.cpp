// SPDX-License-Identifier: BSD-3-Clause
// Robust losses (sba_ext.h: loss, loss_scale) on generated problems with gross outliers: plain
// least squares is pulled away from the ground truth, every robust loss recovers it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "cameras/euclidean.h"
#include "generator/sbagen.h"
#include "sba_ext.h"

namespace euclidean = sbacameras::euclidean;

namespace {

using euclidean::CameraModel;

// A scene whose first two cameras start at the truth; holding them fixed (mcon = 2) fixes the
// gauge, so the refined cameras and points can be compared with the truth directly.
struct Fixture {
  sbagen::Scene scene;
  std::vector<euclidean::Camera> start;

  explicit Fixture(double outliers, std::uint64_t seed) {
    sbagen::Options o;
    o.cameras = 12;
    o.points = 400;
    o.track_min = 3;
    o.track_max = 8;
    o.noise = 0.5;
    o.outliers = outliers;
    o.seed = seed;
    // Start a few pixels from the truth: a redescending loss (Tukey) ignores every residual
    // beyond its scale, so it needs a start where the inliers are within reach.
    o.perturb_rotation = 0.002;
    o.perturb_translation = 0.004;
    o.perturb_points = 0.004;
    std::string err;
    if (!sbagen::generate(o, &scene, &err)) throw std::runtime_error(err);
    start = scene.initial_cameras;
    start[0] = scene.true_cameras[0];
    start[1] = scene.true_cameras[1];
  }
};

struct Fit {
  int ret = 0;
  double info[SBA_INFOSZ] = {};
  sba_ext_result res{};
  double point_med = 0;   // median distance of the refined points from the truth
  double center_rms = 0;  // RMS distance of the refined camera centres from the truth
};

void centre(const euclidean::Camera &c, double out[3]) {
  double R[9];
  euclidean::rotation_matrix(c.q, R);
  for (int r = 0; r < 3; ++r) out[r] = -(R[r] * c.t[0] + R[3 + r] * c.t[1] + R[6 + r] * c.t[2]);
}

Fit fit(Fixture &f, const char *loss, double scale) {
  sbagen::Scene &s = f.scene;
  const CameraModel model(s.kind, f.start, s.initial_points(), 2, 3);
  std::vector<double> p = model.initial_camera_params();
  p.insert(p.end(), model.initial_points().begin(), model.initial_points().end());
  const int n = s.npoints(), m = s.ncameras(), cnp = model.cnp();
  const euclidean::ExpertCallbacks cb =
      euclidean::expert_callbacks(s.kind, euclidean::Refinement::MotionStructure);
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.loss = loss;
  ext.loss_scale = scale;
  Fit out;
  sba_ext_result_init(&out.res);
  ext.result = &out.res;
  out.ret = sba_motstr_levmar_x_ext(n, 0, m, 2, s.measurements.vmask.data(), p.data(), cnp, 3,
                                    s.measurements.x.data(), nullptr, 2, cb.func, cb.fjac,
                                    euclidean::as_adata(model), 300, 0, nullptr, out.info, &ext);
  double sc = 0;
  std::vector<double> dist(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    double sp = 0;
    for (int c = 0; c < 3; ++c) {
      const double d = p[size_t(m) * cnp + i * 3 + c] - s.true_points[size_t(i) * 3 + c];
      sp += d * d;
    }
    dist[size_t(i)] = std::sqrt(sp);
  }
  // The median: a point whose few projections are mostly outliers cannot be recovered by any
  // method, and would dominate an RMS.
  std::nth_element(dist.begin(), dist.begin() + n / 2, dist.end());
  for (int j = 0; j < m; ++j) {
    double a[3], b[3];
    centre(model.camera(j, p.data() + j * cnp), a);
    centre(s.true_cameras[size_t(j)], b);
    for (int c = 0; c < 3; ++c) sc += (a[c] - b[c]) * (a[c] - b[c]);
  }
  out.point_med = dist[size_t(n / 2)];
  out.center_rms = std::sqrt(sc / m);
  return out;
}

TEST(RobustLoss, EveryLossRecoversTheTruthDespiteTenPercentOutliers) {
  Fixture clean(0.0, 7), dirty(0.10, 7);
  ASSERT_GT(dirty.scene.noutliers(), dirty.scene.nprojections() / 12);
  const Fit ref = fit(clean, nullptr, 0);  // least squares without outliers: the yardstick
  const Fit ls = fit(dirty, nullptr, 0);   // least squares with them
  ASSERT_GT(ref.ret, 0);
  ASSERT_GT(ls.ret, 0);
  // The outliers drag least squares well away from the truth.
  EXPECT_GT(ls.point_med, 5 * ref.point_med);
  EXPECT_GT(ls.center_rms, 5 * ref.center_rms);
  EXPECT_EQ(ls.res.robust, 0);
  EXPECT_EQ(ls.res.cost_final, ls.res.sq_error_final);
  for (const char *loss : {"huber", "cauchy", "soft-l1", "tukey"}) {
    // Scale: about three noise standard deviations of the 2-D residual.
    const Fit r = fit(dirty, loss, 2.0);
    ASSERT_GT(r.ret, 0) << loss;
    EXPECT_EQ(r.res.robust, 1);
    EXPECT_EQ(r.info[1], r.res.cost_final);
    EXPECT_LT(r.res.cost_final, r.res.sq_error_final) << loss;
    // Within 2.5 times the error of least squares on clean data (the dragged fit is 50 to 150
    // times off).
    EXPECT_LT(r.point_med, 2.5 * ref.point_med) << loss;
    EXPECT_LT(r.center_rms, 2.5 * ref.center_rms) << loss;
    // The projections it treats as outliers are at least the gross outliers.
    EXPECT_GE(r.res.outliers_final, (long long)(dirty.scene.noutliers() * 9 / 10)) << loss;
    std::printf("%-8s point median %.3g (LS clean %.3g, LS dirty %.3g), centre rms %.3g (%.3g, %.3g), outliers %lld of %zu\n",
                loss, r.point_med, ref.point_med, ls.point_med, r.center_rms, ref.center_rms, ls.center_rms,
                r.res.outliers_final, dirty.scene.noutliers());
  }
}

TEST(RobustLoss, WithoutOutliersALossChangesLittle) {
  Fixture clean(0.0, 8);
  const Fit ls = fit(clean, nullptr, 0), hub = fit(clean, "huber", 3.0);
  ASSERT_GT(hub.ret, 0);
  EXPECT_LT(hub.point_med, 1.2 * ls.point_med + 1e-12);
  EXPECT_NEAR(hub.res.sq_error_final / ls.res.sq_error_final, 1.0, 0.01);
}

// The names a program can offer and check before calling a driver: every one of them is
// accepted by the drivers, and nothing else is.
TEST(RobustLoss, NamesQueryMatchesWhatTheDriversAccept) {
  EXPECT_STREQ(sba_loss_names(), "none huber cauchy soft-l1 tukey");
  for (const char *name : {"none", "huber", "cauchy", "soft-l1", "tukey"}) EXPECT_EQ(sba_loss_valid(name), 1) << name;
  for (const char *name : {"", "Huber", "soft_l1", "huber ", "bisquare"}) EXPECT_EQ(sba_loss_valid(name), 0) << name;
  EXPECT_EQ(sba_loss_valid(nullptr), 0);
  Fixture f(0.0, 9);
  EXPECT_GT(fit(f, "cauchy", 1.0).ret, 0);
}

TEST(RobustLoss, BadLossArgumentsAreRefused) {
  Fixture f(0.0, 9);
  testing::internal::CaptureStderr();
  const Fit a = fit(f, "bisquare", 1.0);
  const Fit b = fit(f, "huber", -1.0);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(a.ret, SBA_ERROR);
  EXPECT_EQ(b.ret, SBA_ERROR);
  EXPECT_NE(err.find("unknown loss \"bisquare\""), std::string::npos) << err;
  EXPECT_NE(err.find("(known: none huber cauchy soft-l1 tukey)"), std::string::npos) << err;
  EXPECT_NE(err.find("loss_scale must be positive"), std::string::npos) << err;
}

// A loss scale whose square or inverse square overflows or underflows is a bad argument,
// refused before iterating with a message naming loss_scale: not an "initial error is not
// finite" that blames x, nor a solve that stops at once having refined nothing.
TEST(RobustLoss, AbsurdLossScalesAreRefusedBeforeIterating) {
  Fixture f(0.0, 10);
  const double scales[] = {1e160,  1e-160, 1e-300, 0x1p512, 0x1p-512, DBL_MAX, DBL_MIN,
                           4.9e-324, -1.0, -1e-3, HUGE_VAL, std::nan("")};
  for (const char *loss : {"huber", "cauchy", "soft-l1", "tukey"})
    for (double scale : scales) {
      char label[64];
      std::snprintf(label, sizeof label, "%s at %g", loss, scale);
      SCOPED_TRACE(label);
      testing::internal::CaptureStderr();
      const Fit r = fit(f, loss, scale);
      const std::string err = testing::internal::GetCapturedStderr();
      EXPECT_EQ(r.ret, SBA_ERROR);
      EXPECT_EQ(r.info[6], 0);  // nothing ran
      EXPECT_EQ(r.info[5], 0);
      char got[64];
      std::snprintf(got, sizeof got, "(got %g)", scale);
      EXPECT_NE(err.find("loss_scale must be positive and within ["), std::string::npos) << err;
      EXPECT_NE(err.find(got), std::string::npos) << err;
      EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    }
}

// At the ends of the accepted range the losses still work: a huge scale makes every residual
// an inlier, so each loss must find the least-squares minimum (no 1 + s/c^2 - 1 cancelling to
// a zero cost); a tiny one must give a finite cost (no s/c^2 overflowing to Inf).
TEST(RobustLoss, LossesWorkAtBothEndsOfTheScaleRange) {
  Fixture f(0.0, 11);
  const Fit ls = fit(f, nullptr, 0);
  ASSERT_GT(ls.ret, 0);
  for (const char *loss : {"huber", "cauchy", "soft-l1", "tukey"}) {
    SCOPED_TRACE(loss);
    const Fit big = fit(f, loss, 0x1p511);
    ASSERT_GT(big.ret, 1);
    EXPECT_GE(big.info[6], 1);
    EXPECT_LE(big.info[6], 5);
    EXPECT_NEAR(big.res.sq_error_final / ls.res.sq_error_final, 1.0, 1e-6);
    EXPECT_NEAR(big.res.cost_final / big.res.sq_error_final, 1.0, 1e-6);
    EXPECT_EQ(big.res.outliers_final, 0);
    const Fit tiny = fit(f, loss, 0x1p-511);
    EXPECT_NE(tiny.ret, SBA_ERROR);
    EXPECT_TRUE(std::isfinite(tiny.info[0]) && tiny.info[0] > 0) << tiny.info[0];
    EXPECT_TRUE(std::isfinite(tiny.info[1])) << tiny.info[1];
  }
}

}  // namespace
