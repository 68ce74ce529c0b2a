// SPDX-License-Identifier: BSD-3-Clause
// The six drivers on synthetic problems with known ground truth.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iterator>
#include <limits>
#include <ostream>
#include <string>
#include <thread>
#include <vector>

#include "sba.h"
#include "synth.h"

namespace {

using synth::kCnp;
using synth::kMnp;
using synth::kPnp;

enum class Mode { MotStr, Mot, Str };

struct Result {
  int ret = 0;
  double info[SBA_INFOSZ] = {};
  std::vector<double> p;
};

Result motstr_x(synth::Problem &pb, int ncon = 0, int mcon = 0, bool analytic = true,
             double *covx = nullptr, int itmax = 150) {
  Result r;
  r.p = pb.p0;
  r.ret = sba_motstr_levmar_x(pb.n, ncon, pb.m, mcon, pb.vmask.data(), r.p.data(), kCnp, kPnp,
                              pb.x.data(), covx, kMnp, synth::func_motstr,
                              analytic ? synth::fjac_motstr : nullptr, &pb, itmax, 0, nullptr, r.info);
  return r;
}

Result motstr_simple(synth::Problem &pb, bool analytic = true) {
  Result r;
  r.p = pb.p0;
  r.ret = sba_motstr_levmar(pb.n, 0, pb.m, 0, pb.vmask.data(), r.p.data(), kCnp, kPnp, pb.x.data(),
                            nullptr, kMnp, synth::proj_motstr,
                            analytic ? synth::projac_motstr : nullptr, &pb, 150, 0, nullptr, r.info);
  return r;
}

// Motion only: points fixed at the truth, cameras start perturbed.
Result mot(synth::Problem &pb, bool expert, bool analytic = true) {
  Result r;
  r.p.assign(pb.p0.begin(), pb.p0.begin() + pb.m * kCnp);
  pb.fixed_points = pb.truth.data() + pb.m * kCnp;
  if (expert)
    r.ret = sba_mot_levmar_x(pb.n, pb.m, 0, pb.vmask.data(), r.p.data(), kCnp, pb.x.data(), nullptr,
                             kMnp, synth::func_mot, analytic ? synth::fjac_mot : nullptr, &pb, 100,
                             0, nullptr, r.info);
  else
    r.ret = sba_mot_levmar(pb.n, pb.m, 0, pb.vmask.data(), r.p.data(), kCnp, pb.x.data(), nullptr,
                           kMnp, synth::proj_mot, analytic ? synth::projac_mot : nullptr, &pb, 100, 0,
                           nullptr, r.info);
  return r;
}

// Structure only: cameras fixed at the truth, points start perturbed.
Result str(synth::Problem &pb, bool expert, bool analytic = true) {
  Result r;
  r.p.assign(pb.p0.begin() + pb.m * kCnp, pb.p0.end());
  pb.fixed_cams = pb.truth.data();
  if (expert)
    r.ret = sba_str_levmar_x(pb.n, 0, pb.m, pb.vmask.data(), r.p.data(), kPnp, pb.x.data(), nullptr,
                             kMnp, synth::func_str, analytic ? synth::fjac_str : nullptr, &pb, 100,
                             0, nullptr, r.info);
  else
    r.ret = sba_str_levmar(pb.n, 0, pb.m, pb.vmask.data(), r.p.data(), kPnp, pb.x.data(), nullptr,
                           kMnp, synth::proj_str, analytic ? synth::projac_str : nullptr, &pb, 100, 0,
                           nullptr, r.info);
  return r;
}

// calls: proj/projac calls per func/fjac call (nvis for the simple drivers, 1 for the expert
// ones); blocks: the small systems per linear system of the mot / str drivers (1 for motstr).
void expect_consistent_info(const Result &r, int calls = 1, int blocks = 1) {
  ASSERT_GE(r.ret, 1);
  EXPECT_EQ(r.info[5], r.ret);
  EXPECT_EQ(r.info[8], double(r.ret) * calls);  // one Jacobian per iteration
  EXPECT_GE(r.info[7], double(r.ret) * calls);
  EXPECT_EQ(std::fmod(r.info[7], calls), 0.0);
  EXPECT_EQ(std::fmod(r.info[9], blocks), 0.0);
  // Every evaluation after the first follows a linear solve.
  EXPECT_GE(r.info[9] / blocks, r.info[7] / calls - 1);
  EXPECT_GE(r.info[6], 1);
  EXPECT_LE(r.info[6], 5);
  EXPECT_LE(r.info[1], r.info[0]);
}

// ---------------------------------------------------------------- noise-free convergence

TEST(Drivers, MotStrExpertNoiseFreeReachesZero) {
  synth::Problem pb = synth::make(80, 6, 0.0, 0.05, 1);
  Result r = motstr_x(pb);
  expect_consistent_info(r);
  EXPECT_GT(r.info[0] / pb.nvis, 1.0);  // the start is visibly off
  EXPECT_LT(r.info[1] / pb.nvis, 1e-12);
  EXPECT_LE(r.ret, 60);
  EXPECT_NEAR(synth::sq_error(pb, r.p.data()), r.info[1], 1e-12);
}

TEST(Drivers, MotStrSimpleNoiseFreeReachesZero) {
  synth::Problem pb = synth::make(80, 6, 0.0, 0.05, 1);
  Result r = motstr_simple(pb);
  expect_consistent_info(r, pb.nvis);
  EXPECT_LT(r.info[1] / pb.nvis, 1e-12);
  // The simple driver is an adapter onto the same core: the same path, step by step.
  Result e = motstr_x(pb);
  EXPECT_EQ(r.ret, e.ret);
  EXPECT_EQ(r.info[7], e.info[7] * pb.nvis);
  EXPECT_EQ(r.info[9], e.info[9]);
}

TEST(Drivers, MotionOnlyRecoversCameras) {
  synth::Problem pb = synth::make(80, 6, 0.0, 0.05, 2);
  for (bool expert : {true, false}) {
    Result r = mot(pb, expert);
    expect_consistent_info(r, expert ? 1 : pb.nvis, pb.m);
    EXPECT_LT(r.info[1] / pb.nvis, 1e-12);
    for (int q = 0; q < pb.m * kCnp; ++q) EXPECT_NEAR(r.p[q], pb.truth[q], 1e-6) << q;
  }
}

TEST(Drivers, StructureOnlyRecoversPoints) {
  synth::Problem pb = synth::make(80, 6, 0.0, 0.05, 3);
  for (bool expert : {true, false}) {
    Result r = str(pb, expert);
    expect_consistent_info(r, expert ? 1 : pb.nvis, pb.n);
    EXPECT_LT(r.info[1] / pb.nvis, 1e-12);
    for (int q = 0; q < pb.n * kPnp; ++q) EXPECT_NEAR(r.p[q], pb.truth[pb.m * kCnp + q], 1e-6) << q;
  }
}

// ---------------------------------------------------------------- noise

TEST(Drivers, NoisyDataConvergesToTheNoiseLevel) {
  const double sigma = 0.5;
  synth::Problem pb = synth::make(200, 8, sigma, 0.05, 4);
  Result r = motstr_x(pb);
  expect_consistent_info(r);
  // E||e||^2 = sigma^2 (measurements - effective unknowns); the gauge has 7 dimensions.
  const double nobs = 2.0 * pb.nvis, nfree = pb.m * kCnp + pb.n * kPnp - 7;
  const double expected = sigma * sigma * (nobs - nfree);
  EXPECT_GT(r.info[1], 0.8 * expected);
  EXPECT_LT(r.info[1], 1.2 * expected);
  // And not below what the truth scores by more than the fit can explain.
  EXPECT_LT(r.info[1], synth::sq_error(pb, pb.truth.data()));
}

TEST(Drivers, FiniteDifferencesReachTheAnalyticMinimum) {
  synth::Problem pb = synth::make(120, 6, 0.5, 0.05, 5);
  Result an = motstr_x(pb), fd = motstr_x(pb, 0, 0, false);
  Result san = motstr_simple(pb), sfd = motstr_simple(pb, false);
  ASSERT_GT(an.ret, 0);
  ASSERT_GT(fd.ret, 0);
  ASSERT_GT(sfd.ret, 0);
  EXPECT_NEAR(fd.info[1] / an.info[1], 1.0, 1e-6);
  EXPECT_NEAR(sfd.info[1] / san.info[1], 1.0, 1e-6);
  // The evaluations that build a finite-difference Jacobian are not counted (as in 1.6).
  EXPECT_LE(fd.info[7], fd.info[9] + 1);
  EXPECT_EQ(fd.info[0], an.info[0]);
  for (bool expert : {true, false}) {
    Result ma = mot(pb, expert), mf = mot(pb, expert, false);
    EXPECT_NEAR(mf.info[1] / ma.info[1], 1.0, 1e-6);
    Result sa = str(pb, expert), sf = str(pb, expert, false);
    EXPECT_NEAR(sf.info[1] / sa.info[1], 1.0, 1e-6);
  }
}

// info[7..9] with sba 1.6's meaning: func calls of the LM loop only (the initial one and
// one per trial point), simple-driver counts in proj/projac calls, and one linear system per
// free camera (point) block for the motion-only (structure-only) drivers.
TEST(Drivers, CountersAsSba16CountsThem) {
  synth::Problem pb = synth::make(60, 6, 0.5, 0.05, 31);
  const Result an = motstr_x(pb), fd = motstr_x(pb, 0, 0, false);
  ASSERT_GT(an.ret, 0);
  ASSERT_GT(fd.ret, 0);
  // A trial point is evaluated after every linear system solved but one that ends the run
  // (stop 2); a system that fails to factor is counted too (after a rejected step 1.6's retries
  // fail until the damping dominates), and every iteration but a last one ended by stop 2
  // takes a trial point.
  for (const Result *r : {&an, &fd}) {
    EXPECT_LE(r->info[7], r->info[9] + 1);
    EXPECT_GE(r->info[7], r->info[8]);
    EXPECT_EQ(r->info[8], r->ret);
  }
  const Result sim = motstr_simple(pb), simfd = motstr_simple(pb, false);
  EXPECT_EQ(sim.ret, an.ret);
  EXPECT_EQ(sim.info[7], an.info[7] * pb.nvis);
  EXPECT_EQ(sim.info[8], an.info[8] * pb.nvis);
  EXPECT_EQ(sim.info[9], an.info[9]);
  EXPECT_EQ(simfd.info[8], simfd.ret * double(pb.nvis));
  EXPECT_LE(simfd.info[7], (simfd.info[9] + 1) * pb.nvis);

  // Motion only with two cameras fixed: four blocks per system.
  pb.fixed_points = pb.truth.data() + pb.m * kCnp;
  std::vector<double> cams(pb.p0.begin(), pb.p0.begin() + pb.m * kCnp);
  double info[SBA_INFOSZ];
  int ret = sba_mot_levmar_x(pb.n, pb.m, 2, pb.vmask.data(), cams.data(), kCnp, pb.x.data(), nullptr,
                             kMnp, synth::func_mot, synth::fjac_mot, &pb, 100, 0, nullptr, info);
  ASSERT_GT(ret, 0);
  EXPECT_EQ(std::fmod(info[9], pb.m - 2), 0.0) << info[9];
  EXPECT_GE(info[9], (pb.m - 2) * (info[7] - 1));
  EXPECT_LE(info[9], (pb.m - 2) * info[7]);
  // Structure only with ten points fixed: fifty blocks per system.
  pb.fixed_cams = pb.truth.data();
  std::vector<double> pts(pb.p0.begin() + pb.m * kCnp, pb.p0.end());
  ret = sba_str_levmar_x(pb.n, 10, pb.m, pb.vmask.data(), pts.data(), kPnp, pb.x.data(), nullptr,
                         kMnp, synth::func_str, synth::fjac_str, &pb, 100, 0, nullptr, info);
  ASSERT_GT(ret, 0);
  EXPECT_EQ(std::fmod(info[9], pb.n - 10), 0.0) << info[9];
  EXPECT_GE(info[9], (pb.n - 10) * (info[7] - 1));
  EXPECT_LE(info[9], (pb.n - 10) * info[7]);
}

// ---------------------------------------------------------------- covariances

TEST(Drivers, HugeCovarianceMeansTheMeasurementBarelyPulls) {
  synth::Problem pb = synth::make(60, 6, 0.0, 0.02, 6);
  const int bad = 17;  // one measurement moved by 30 pixels
  pb.x[2 * bad] += 30.0;
  std::vector<double> cov(size_t(pb.nvis) * 4, 0.0);
  for (int k = 0; k < pb.nvis; ++k) cov[4 * k] = cov[4 * k + 3] = 1.0;
  Result plain = motstr_x(pb, 0, 0, true, cov.data());
  cov[4 * bad] = cov[4 * bad + 3] = 1e8;
  Result down = motstr_x(pb, 0, 0, true, cov.data());
  ASSERT_GT(plain.ret, 0);
  ASSERT_GT(down.ret, 0);
  // Residual left on the moved measurement: small when it is trusted (the others bend),
  // nearly all 30 pixels when its variance is huge.
  auto residual_x = [&](const Result &r) {
    std::vector<double> hx(size_t(pb.nvis) * 2);
    sba_crsm idx{};
    std::vector<int> rowptr, colidx, val;
    int k = 0;
    for (int i = 0; i < pb.n; ++i) {
      rowptr.push_back(k);
      for (int j = 0; j < pb.m; ++j)
        if (pb.vmask[size_t(i) * pb.m + j]) colidx.push_back(j), val.push_back(k++);
    }
    rowptr.push_back(k);
    idx = {pb.n, pb.m, k, val.data(), colidx.data(), rowptr.data()};
    std::vector<double> p = r.p;
    synth::func_motstr(p.data(), &idx, nullptr, nullptr, hx.data(), &pb);
    return pb.x[2 * bad] - hx[2 * bad];
  };
  EXPECT_LT(residual_x(plain), 25.0);
  EXPECT_GT(residual_x(down), 29.9);
  EXPECT_LT(down.info[1], 30.0 * 30.0 / 1e8 + 1e-6);  // the weighted error is tiny
  // Identity covariances are the unweighted problem.
  Result none = motstr_x(pb);
  EXPECT_NEAR(none.info[1], plain.info[1], 1e-9 * plain.info[1]);
}

TEST(Drivers, NonPositiveDefiniteCovarianceIsRefused) {
  synth::Problem pb = synth::make(30, 4, 0.0, 0.02, 7);
  std::vector<double> cov(size_t(pb.nvis) * 4, 0.0);
  for (int k = 0; k < pb.nvis; ++k) cov[4 * k] = cov[4 * k + 3] = 1.0;
  cov[4 * 5 + 3] = -1.0;
  testing::internal::CaptureStderr();
  Result r = motstr_x(pb, 0, 0, true, cov.data());
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(r.ret, SBA_ERROR);
  EXPECT_NE(err.find("covariance of measurement 5"), std::string::npos) << err;
  EXPECT_EQ(r.p, pb.p0);
}

// ---------------------------------------------------------------- fixed cameras / points

TEST(Drivers, FixedCamerasAndPointsStayBitForBit) {
  synth::Problem pb = synth::make(100, 6, 0.3, 0.05, 8);
  const int mcon = 2, ncon = 7;
  for (bool analytic : {true, false}) {
    Result r = motstr_x(pb, ncon, mcon, analytic);
    ASSERT_GT(r.ret, 0);
    EXPECT_LT(r.info[1], r.info[0]);
    EXPECT_EQ(0, std::memcmp(r.p.data(), pb.p0.data(), sizeof(double) * mcon * kCnp));
    EXPECT_EQ(0, std::memcmp(r.p.data() + pb.m * kCnp, pb.p0.data() + pb.m * kCnp,
                             sizeof(double) * ncon * kPnp));
    EXPECT_NE(0, std::memcmp(r.p.data() + mcon * kCnp, pb.p0.data() + mcon * kCnp, sizeof(double)));
  }
}

TEST(Drivers, AllCamerasFixedRefinesStructureLikeTheStrDriver) {
  synth::Problem pb = synth::make(60, 5, 0.3, 0.05, 9);
  pb.p0.assign(pb.truth.begin(), pb.truth.begin() + pb.m * kCnp);  // cameras at the truth
  synth::Problem start = synth::make(60, 5, 0.3, 0.05, 9);
  pb.p0.insert(pb.p0.end(), start.p0.begin() + pb.m * kCnp, start.p0.end());
  Result all = motstr_x(pb, 0, pb.m);
  Result s = str(pb, true);
  ASSERT_GT(all.ret, 0);
  ASSERT_GT(s.ret, 0);
  EXPECT_NEAR(all.info[1], s.info[1], 1e-9 * s.info[1]);
  for (int q = 0; q < pb.n * kPnp; ++q) EXPECT_NEAR(all.p[pb.m * kCnp + q], s.p[q], 1e-7);
}

TEST(Drivers, AllPointsFixedRefinesMotionLikeTheMotDriver) {
  synth::Problem pb = synth::make(60, 5, 0.3, 0.05, 10);
  std::copy(pb.truth.begin() + pb.m * kCnp, pb.truth.end(), pb.p0.begin() + pb.m * kCnp);
  Result all = motstr_x(pb, pb.n, 0);
  Result m = mot(pb, true);
  ASSERT_GT(all.ret, 0);
  ASSERT_GT(m.ret, 0);
  EXPECT_NEAR(all.info[1], m.info[1], 1e-9 * m.info[1]);
  for (int q = 0; q < pb.m * kCnp; ++q) EXPECT_NEAR(all.p[q], m.p[q], 1e-7);
}

// ---------------------------------------------------------------- Jacobian check

struct WrongJac {
  synth::Problem *pb;
  int point, camera;
};

void fjac_with_error(double *p, sba_crsm *idx, int *r, int *s, double *jac, void *adata) {
  const WrongJac &w = *static_cast<WrongJac *>(adata);
  synth::fjac_motstr(p, idx, r, s, jac, w.pb);
  const int k = sba_crsm_elmidx(idx, w.point, w.camera);
  jac[idx->val[k] * kMnp * (kCnp + kPnp) + 2] += 5.0;  // row 0 of A_ij, column 2
}
void func_wrapped(double *p, sba_crsm *idx, int *r, int *s, double *hx, void *adata) {
  synth::func_motstr(p, idx, r, s, hx, static_cast<WrongJac *>(adata)->pb);
}

TEST(Drivers, JacobianCheckAcceptsACorrectJacobian) {
  synth::Problem pb = synth::make(40, 4, 0.0, 0.05, 11);
  testing::internal::CaptureStderr();
  Result r = motstr_x(pb, 1, 1, true, nullptr, 0);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(r.ret, 0);
  EXPECT_EQ(r.p, pb.p0);
  EXPECT_NE(err.find("agree with finite differences"), std::string::npos) << err;
  EXPECT_EQ(err.find("probably wrong"), std::string::npos) << err;
}

TEST(Drivers, JacobianCheckReportsAWrongEntry) {
  synth::Problem pb = synth::make(40, 4, 0.0, 0.05, 11);
  pb.vmask[size_t(3) * pb.m + 1] = 1;  // make sure (3,1) is visible
  synth::Problem ok = synth::make(40, 4, 0.0, 0.05, 11);
  (void)ok;
  // Rebuild x for the changed mask.
  pb.x.clear();
  pb.nvis = 0;
  for (int i = 0; i < pb.n; ++i)
    for (int j = 0; j < pb.m; ++j)
      if (pb.vmask[size_t(i) * pb.m + j]) {
        double xij[2];
        synth::project(pb.truth.data() + j * kCnp, pb.truth.data() + pb.m * kCnp + i * 3, xij, nullptr, nullptr);
        pb.x.insert(pb.x.end(), xij, xij + 2);
        ++pb.nvis;
      }
  WrongJac w{&pb, 3, 1};
  std::vector<double> p = pb.p0;
  double info[SBA_INFOSZ];
  testing::internal::CaptureStderr();
  const int ret = sba_motstr_levmar_x(pb.n, 0, pb.m, 0, pb.vmask.data(), p.data(), kCnp, kPnp,
                                      pb.x.data(), nullptr, kMnp, func_wrapped, fjac_with_error, &w,
                                      0, 0, nullptr, info);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(ret, 0);
  EXPECT_EQ(p, pb.p0);
  EXPECT_NE(err.find("(element 0 of the projection of point 3 on camera 1) is probably wrong: "
                     "d/d(camera 1 parameter 2)"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("1 of "), std::string::npos) << err;
}

// ---------------------------------------------------------------- NaN during the solve

struct NanAfter {
  synth::Problem *pb;
  int calls = 0, limit = 0;
};
void func_nan_after(double *p, sba_crsm *idx, int *r, int *s, double *hx, void *adata) {
  NanAfter &w = *static_cast<NanAfter *>(adata);
  synth::func_motstr(p, idx, r, s, hx, w.pb);
  if (++w.calls > w.limit) hx[1] = std::numeric_limits<double>::quiet_NaN();
}
void fjac_nan_after(double *p, sba_crsm *idx, int *r, int *s, double *jac, void *adata) {
  synth::fjac_motstr(p, idx, r, s, jac, static_cast<NanAfter *>(adata)->pb);
}

TEST(Drivers, NanFromFuncMidwayIsAnErrorWithReason7) {
  synth::Problem pb = synth::make(60, 5, 0.3, 0.05, 12);
  NanAfter w{&pb, 0, 3};
  std::vector<double> p = pb.p0;
  double info[SBA_INFOSZ];
  testing::internal::CaptureStderr();
  const int ret = sba_motstr_levmar_x(pb.n, 0, pb.m, 0, pb.vmask.data(), p.data(), kCnp, kPnp,
                                      pb.x.data(), nullptr, kMnp, func_nan_after, fjac_nan_after,
                                      &w, 150, 0, nullptr, info);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(ret, SBA_ERROR);
  EXPECT_EQ(info[6], 7);
  EXPECT_NE(err.find("NaN"), std::string::npos);
  // p is the last accepted estimate: finite, better than the start, and scored by info[1].
  for (double v : p) ASSERT_TRUE(std::isfinite(v));
  EXPECT_LT(info[1], info[0]);
  EXPECT_NEAR(synth::sq_error(pb, p.data()), info[1], 1e-9 * info[1]);
}

TEST(Drivers, NanJacobianIsAnError) {
  synth::Problem pb = synth::make(30, 4, 0.0, 0.05, 13);
  std::vector<double> p = pb.p0;
  double info[SBA_INFOSZ];
  auto bad_jac = [](double *, sba_crsm *idx, int *, int *, double *jac, void *) {
    for (int q = 0; q < idx->nnz * kMnp * (kCnp + kPnp); ++q) jac[q] = 1.0;
    jac[3] = std::numeric_limits<double>::infinity();
  };
  testing::internal::CaptureStderr();
  const int ret = sba_motstr_levmar_x(pb.n, 0, pb.m, 0, pb.vmask.data(), p.data(), kCnp, kPnp,
                                      pb.x.data(), nullptr, kMnp, synth::func_motstr, bad_jac, &pb,
                                      50, 0, nullptr, info);
  testing::internal::GetCapturedStderr();
  EXPECT_EQ(ret, SBA_ERROR);
  EXPECT_EQ(info[6], 7);
  EXPECT_EQ(p, pb.p0);
}

// ---------------------------------------------------------------- bad arguments

TEST(Drivers, BadArgumentsAreRefusedWithAMessage) {
  synth::Problem pb = synth::make(20, 3, 0.0, 0.05, 14);
  std::vector<double> p = pb.p0;
  auto call = [&](int n, int ncon, int m, int mcon, char *vmask, double *pp, int cnp, int pnp,
                  double *x, int mnp, bool func, int itmax) {
    double info[SBA_INFOSZ];
    for (double &v : info) v = -42;
    testing::internal::CaptureStderr();
    const int ret = sba_motstr_levmar_x(n, ncon, m, mcon, vmask, pp, cnp, pnp, x, nullptr, mnp,
                                        func ? synth::func_motstr : nullptr, synth::fjac_motstr, &pb,
                                        itmax, 0, nullptr, info);
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_EQ(ret, SBA_ERROR);
    EXPECT_EQ(info[6], 0);  // filled, not left at -42
    EXPECT_EQ(info[5], 0);
    return err;
  };
  char *vm = pb.vmask.data();
  double *x = pb.x.data();
  EXPECT_NE(call(0, 0, pb.m, 0, vm, p.data(), 6, 3, x, 2, true, 10).find("n must be positive"), std::string::npos);
  EXPECT_NE(call(pb.n, 0, -1, 0, vm, p.data(), 6, 3, x, 2, true, 10).find("m must be positive"), std::string::npos);
  EXPECT_NE(call(pb.n, 0, pb.m, 0, vm, p.data(), 0, 3, x, 2, true, 10).find("cnp"), std::string::npos);
  EXPECT_NE(call(pb.n, 0, pb.m, 0, vm, p.data(), 6, 0, x, 2, true, 10).find("pnp"), std::string::npos);
  EXPECT_NE(call(pb.n, 0, pb.m, 0, vm, p.data(), 6, 3, x, 0, true, 10).find("mnp"), std::string::npos);
  EXPECT_NE(call(pb.n, 0, pb.m, pb.m + 1, vm, p.data(), 6, 3, x, 2, true, 10).find("mcon"), std::string::npos);
  EXPECT_NE(call(pb.n, -1, pb.m, 0, vm, p.data(), 6, 3, x, 2, true, 10).find("ncon"), std::string::npos);
  EXPECT_NE(call(pb.n, pb.n + 1, pb.m, 0, vm, p.data(), 6, 3, x, 2, true, 10).find("ncon"), std::string::npos);
  EXPECT_NE(call(pb.n, 0, pb.m, 0, nullptr, p.data(), 6, 3, x, 2, true, 10).find("vmask"), std::string::npos);
  EXPECT_NE(call(pb.n, 0, pb.m, 0, vm, nullptr, 6, 3, x, 2, true, 10).find("p is NULL"), std::string::npos);
  EXPECT_NE(call(pb.n, 0, pb.m, 0, vm, p.data(), 6, 3, nullptr, 2, true, 10).find("x is NULL"), std::string::npos);
  EXPECT_NE(call(pb.n, 0, pb.m, 0, vm, p.data(), 6, 3, x, 2, false, 10).find("NULL"), std::string::npos);
  EXPECT_NE(call(pb.n, 0, pb.m, 0, vm, p.data(), 6, 3, x, 2, true, -1).find("itmax"), std::string::npos);
  EXPECT_NE(call(pb.n, pb.n, pb.m, pb.m, vm, p.data(), 6, 3, x, 2, true, 10).find("nothing to refine"), std::string::npos);
  std::vector<char> empty(pb.vmask.size(), 0);
  EXPECT_NE(call(pb.n, 0, pb.m, 0, empty.data(), p.data(), 6, 3, x, 2, true, 10).find("nvis"), std::string::npos);
  p[4] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(call(pb.n, 0, pb.m, 0, vm, p.data(), 6, 3, x, 2, true, 10).find("p[4] is not finite"), std::string::npos);
  p = pb.p0;
  std::vector<double> xb = pb.x;
  xb[7] = std::numeric_limits<double>::infinity();
  EXPECT_NE(call(pb.n, 0, pb.m, 0, vm, p.data(), 6, 3, xb.data(), 2, true, 10).find("x[7] is not finite"), std::string::npos);
  EXPECT_EQ(p, pb.p0);
}

TEST(Drivers, FewerMeasurementsThanUnknownsIsRefused) {
  // 10 points seen twice each: 40 measurements for 12 + 30 unknowns.
  synth::Problem pb = synth::make(10, 2, 0.0, 0.05, 15, 1.0);
  std::vector<double> p = pb.p0;
  testing::internal::CaptureStderr();
  const int ret = sba_motstr_levmar_x(pb.n, 0, pb.m, 0, pb.vmask.data(), p.data(), kCnp, kPnp,
                                      pb.x.data(), nullptr, kMnp, synth::func_motstr, synth::fjac_motstr,
                                      &pb, 10, 0, nullptr, nullptr);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(ret, SBA_ERROR);
  EXPECT_NE(err.find("fewer measurements (40) than free parameters (42)"), std::string::npos) << err;
}

TEST(Drivers, SimpleAndMotStrDriversRejectBadArgumentsToo) {
  synth::Problem pb = synth::make(20, 3, 0.0, 0.05, 16);
  std::vector<double> p = pb.p0;
  testing::internal::CaptureStderr();
  EXPECT_EQ(sba_motstr_levmar(pb.n, 0, pb.m, 0, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(), nullptr,
                              kMnp, nullptr, nullptr, &pb, 10, 0, nullptr, nullptr), SBA_ERROR);
  EXPECT_EQ(sba_mot_levmar(pb.n, pb.m, -2, pb.vmask.data(), p.data(), kCnp, pb.x.data(), nullptr, kMnp,
                           synth::proj_mot, nullptr, &pb, 10, 0, nullptr, nullptr), SBA_ERROR);
  EXPECT_EQ(sba_str_levmar(pb.n, 0, pb.m, pb.vmask.data(), p.data(), 0, pb.x.data(), nullptr, kMnp,
                           synth::proj_str, nullptr, &pb, 10, 0, nullptr, nullptr), SBA_ERROR);
  EXPECT_EQ(sba_mot_levmar_x(pb.n, pb.m, 0, pb.vmask.data(), p.data(), kCnp, pb.x.data(), nullptr, 0,
                             synth::func_mot, nullptr, &pb, 10, 0, nullptr, nullptr), SBA_ERROR);
  EXPECT_EQ(sba_str_levmar_x(0, 0, pb.m, pb.vmask.data(), p.data(), kPnp, pb.x.data(), nullptr, kMnp,
                             synth::func_str, nullptr, &pb, 10, 0, nullptr, nullptr), SBA_ERROR);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("sba_motstr_levmar: the projection function"), std::string::npos) << err;
  EXPECT_NE(err.find("sba_mot_levmar: mcon"), std::string::npos) << err;
  EXPECT_NE(err.find("sba_str_levmar: pnp"), std::string::npos) << err;
  EXPECT_NE(err.find("sba_mot_levmar_x: mnp"), std::string::npos) << err;
  EXPECT_NE(err.find("sba_str_levmar_x: n must"), std::string::npos) << err;
  EXPECT_EQ(p, pb.p0);
}

// ---------------------------------------------------------------- options and quietness

TEST(Drivers, OptsAndInfoMayBeNullAndNothingIsPrinted) {
  synth::Problem pb = synth::make(50, 5, 0.2, 0.05, 17);
  std::vector<double> p = pb.p0, q = pb.p0;
  const double opts[SBA_OPTSSZ] = {SBA_INIT_MU, SBA_STOP_THRESH, SBA_STOP_THRESH, SBA_STOP_THRESH, 0.0};
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  const int r1 = sba_motstr_levmar_x(pb.n, 0, pb.m, 0, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(),
                                     nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 150, 0,
                                     nullptr, nullptr);
  const int r2 = sba_motstr_levmar_x(pb.n, 0, pb.m, 0, pb.vmask.data(), q.data(), kCnp, kPnp, pb.x.data(),
                                     nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 150, 0,
                                     opts, nullptr);
  EXPECT_EQ(testing::internal::GetCapturedStdout(), "");
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
  EXPECT_GT(r1, 0);
  EXPECT_EQ(r1, r2);
  EXPECT_EQ(p, q);
}

TEST(Drivers, ItmaxIsHonouredWithReason3) {
  synth::Problem pb = synth::make(50, 5, 0.2, 0.2, 18);
  Result r = motstr_x(pb, 0, 0, true, nullptr, 3);
  EXPECT_EQ(r.ret, 3);
  EXPECT_EQ(r.info[6], 3);
  EXPECT_EQ(r.info[8], 3);
}

TEST(Drivers, LooseEps1StopsWithReason1) {
  synth::Problem pb = synth::make(50, 5, 0.2, 0.05, 19);
  std::vector<double> p = pb.p0;
  double info[SBA_INFOSZ];
  const double opts[SBA_OPTSSZ] = {1e-3, 1e12, 1e-12, 1e-12, 0.0};
  const int ret = sba_motstr_levmar_x(pb.n, 0, pb.m, 0, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(),
                                      nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 50, 0,
                                      opts, info);
  EXPECT_EQ(ret, 1);
  EXPECT_EQ(info[6], 1);
  EXPECT_EQ(info[3], 0.0);
  EXPECT_EQ(info[9], 0);
  EXPECT_EQ(p, pb.p0);
}

TEST(Drivers, Eps4StopsOnSmallRelativeReductionWithReason4) {
  synth::Problem pb = synth::make(50, 5, 0.5, 0.05, 20);
  std::vector<double> p = pb.p0;
  double info[SBA_INFOSZ];
  const double opts[SBA_OPTSSZ] = {1e-3, 1e-12, 1e-12, 1e-12, 1e-2};
  const int ret = sba_motstr_levmar_x(pb.n, 0, pb.m, 0, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(),
                                      nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 150, 0,
                                      opts, info);
  EXPECT_GT(ret, 0);
  EXPECT_EQ(info[6], 4);
  Result full = motstr_x(pb);
  EXPECT_LT(ret, full.ret);
}

// ---------------------------------------------------------------- stop 4 at eps4 = 0

// An expert driver's func and fjac with the squared error of every evaluation recorded.
struct Recorder {
  synth::Problem *pb;
  void (*func)(double *, sba_crsm *, int *, int *, double *, void *);
  void (*fjac)(double *, sba_crsm *, int *, int *, double *, void *);
  std::vector<double> errors;
};

void recording_func(double *p, sba_crsm *idx, int *r, int *s, double *hx, void *adata) {
  Recorder &rec = *static_cast<Recorder *>(adata);
  rec.func(p, idx, r, s, hx, rec.pb);
  double e = 0.0;
  for (size_t q = 0; q < rec.pb->x.size(); ++q) e += (rec.pb->x[q] - hx[q]) * (rec.pb->x[q] - hx[q]);
  rec.errors.push_back(e);
}

void recording_fjac(double *p, sba_crsm *idx, int *r, int *s, double *jac, void *adata) {
  Recorder &rec = *static_cast<Recorder *>(adata);
  rec.fjac(p, idx, r, s, jac, rec.pb);
}

// sba 1.6's test fires through rounding, about once in four accepted steps whose relative
// decrease is far below 1e-8, so over a handful of noisy problems some runs of every driver
// end with reason 4 at the default opts (eps4 = 0), each after a strict decrease too small
// for the exact test. The simple drivers follow their expert driver's path step by step.
TEST(Drivers, Eps4ZeroEndsRunsWithReason4ByCancellationInEveryDriver) {
  for (Mode mode : {Mode::MotStr, Mode::Mot, Mode::Str}) {
    SCOPED_TRACE(mode == Mode::MotStr ? "motstr" : mode == Mode::Mot ? "mot" : "str");
    int stalled = 0;
    for (unsigned seed = 1; seed <= 8; ++seed) {
      synth::Problem pb = synth::make(50, 5, 0.5, 0.05, 100 + seed);
      pb.fixed_points = pb.truth.data() + pb.m * kCnp;
      pb.fixed_cams = pb.truth.data();
      Result x, s;
      Recorder rec{&pb, nullptr, nullptr, {}};
      if (mode == Mode::MotStr) {
        rec.func = synth::func_motstr;
        rec.fjac = synth::fjac_motstr;
        x.p = pb.p0;
        x.ret = sba_motstr_levmar_x(pb.n, 0, pb.m, 0, pb.vmask.data(), x.p.data(), kCnp, kPnp,
                                    pb.x.data(), nullptr, kMnp, recording_func, recording_fjac, &rec,
                                    150, 0, nullptr, x.info);
        s = motstr_simple(pb);
      } else if (mode == Mode::Mot) {
        rec.func = synth::func_mot;
        rec.fjac = synth::fjac_mot;
        x.p.assign(pb.p0.begin(), pb.p0.begin() + pb.m * kCnp);
        x.ret = sba_mot_levmar_x(pb.n, pb.m, 0, pb.vmask.data(), x.p.data(), kCnp, pb.x.data(),
                                 nullptr, kMnp, recording_func, recording_fjac, &rec, 100, 0,
                                 nullptr, x.info);
        s = mot(pb, false);
      } else {
        rec.func = synth::func_str;
        rec.fjac = synth::fjac_str;
        x.p.assign(pb.p0.begin() + pb.m * kCnp, pb.p0.end());
        x.ret = sba_str_levmar_x(pb.n, 0, pb.m, pb.vmask.data(), x.p.data(), kPnp, pb.x.data(),
                                 nullptr, kMnp, recording_func, recording_fjac, &rec, 100, 0,
                                 nullptr, x.info);
        s = str(pb, false);
      }
      ASSERT_GT(x.ret, 0) << "seed " << seed;
      EXPECT_EQ(s.ret, x.ret) << "seed " << seed;
      EXPECT_EQ(s.info[6], x.info[6]) << "seed " << seed;
      if (x.info[6] != 4) continue;
      ++stalled;
      // Stop 4 is tested after an accepted step, and nothing is evaluated after it.
      ASSERT_GE(rec.errors.size(), 2u);
      const double last = rec.errors.back();
      const double before = *std::min_element(rec.errors.begin(), rec.errors.end() - 1);
      EXPECT_LT(last, before) << "seed " << seed;
      EXPECT_LT((before - last) / before, 4e-8) << "seed " << seed;
    }
    EXPECT_GE(stalled, 2);
  }
}

// ---------------------------------------------------------------- sba 1.6's retries and lines

// Problems on which sba 1.6 rejects steps early and retries them: synth::make(20, 4, 0.5,
// perturb, seed) from opts[0] = tau, itmax 150, the first camera fixed in the motion-and-
// structure driver. 1.6's figures (its library, OpenBLAS at 1 and 2 threads: the same) are
// the damping of its first trial points as its verbose 2 prints them (%8g), and the counts of
// the whole run. A rejected step there is retried on the blocks the previous attempt left
// (accumulated damping; in the motion-and-structure driver, the inverse's diagonal on V_i's),
// which the damping shows: after the first rejection of the motion-and-structure run, 1.6
// retries at 574181, where a retry from the undamped blocks succeeds at 17.5226.
struct Sba16Retries {
  Mode mode;
  bool expert;
  double perturb, tau;
  unsigned seed;
  const char *initial_line;
  std::vector<const char *> damping;  // the first trial points'
  int iterations, reason, nfev, njev, nlin;
  double error;
};

const char *const kMotstrDamping[] = {"0.273791", "574181", "191394", "63797.9", "21266", "7088.66", "2362.89",
                                      "787.629", "262.543", "87.5143", "29.1714", "9.72381", "9957.18", "16732.3",
                                      "5577.43", "1859.14", "619.715", "206.572", "68.8572", "22.9524"};
const char *const kMotDamping[] = {"0.000136658", "0.000273317", "0.00109327", "0.00874614", "0.139938",
                                   "4.47803", "286.594", "98.8438", "32.9479", "65.8959", "119.189", "129.704",
                                   "129.704", "259.408", "442.879", "598.338", "759.344", "1238.86", "1542.52",
                                   "3085.05"};
const char *const kStrDamping[] = {"0.338812", "0.126376", "0.252751", "1.011", "1.01178", "2.02356", "2.02925",
                                   "1.98741", "1.54562", "0.785858", "1.57172", "0.572995", "1.14599", "4.58396",
                                   "36.6717", "12.2239", "5.16437", "1.72146", "0.573819"};

std::vector<const char *> list(const char *const *b, const char *const *e) { return {b, e}; }

const Sba16Retries kRetries[] = {
    {Mode::MotStr, true, 2.0, 1e-6, 4, "initial motstr-SBA error 1.99911e+06 [38444.5]",
     list(std::begin(kMotstrDamping), std::end(kMotstrDamping)), 27, 2, 30, 27, 43, 6.85657411},
    {Mode::MotStr, false, 2.0, 1e-6, 4, "initial motstr-SBA error 1.99911e+06 [38444.5]",
     list(std::begin(kMotstrDamping), std::end(kMotstrDamping)), 27, 2, 1560, 1404, 43, 6.85657411},
    {Mode::Mot, true, 10.0, 1e-9, 4, "initial mot-SBA error 1.25704e+07 [241739]",
     list(std::begin(kMotDamping), std::end(kMotDamping)), 56, 2, 69, 56, 276, 16.7554311},
    {Mode::Mot, false, 10.0, 1e-9, 4, "initial mot-SBA error 1.25704e+07 [241739]",
     list(std::begin(kMotDamping), std::end(kMotDamping)), 56, 2, 3588, 2912, 276, 16.7554311},
    {Mode::Str, true, 6.0, 1e-9, 3, "initial str-SBA error 8.73532e+07 [1.58824e+06]",
     list(std::begin(kStrDamping), std::end(kStrDamping)), 14, 4, 22, 14, 420, 9.58244637},
    {Mode::Str, false, 6.0, 1e-9, 3, "initial str-SBA error 8.73532e+07 [1.58824e+06]",
     list(std::begin(kStrDamping), std::end(kStrDamping)), 14, 4, 1210, 770, 420, 9.58244637},
};

// The driver of c on its problem, at `verbose`, its stdout captured.
Result run_retry_case(const Sba16Retries &c, int verbose, std::string *out) {
  synth::Problem pb = synth::make(20, 4, 0.5, c.perturb, c.seed);
  pb.fixed_points = pb.truth.data() + pb.m * kCnp;
  pb.fixed_cams = pb.truth.data();
  Result r;
  r.p = pb.p0;
  const double opts[SBA_OPTSSZ] = {c.tau, 1e-12, 1e-12, 1e-12, 0.0};
  double *cams = r.p.data(), *pts = r.p.data() + pb.m * kCnp;
  testing::internal::CaptureStdout();
  switch (c.mode) {
    case Mode::MotStr:
      r.ret = c.expert ? sba_motstr_levmar_x(pb.n, 0, pb.m, 1, pb.vmask.data(), cams, kCnp, kPnp, pb.x.data(),
                                             nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 150,
                                             verbose, opts, r.info)
                       : sba_motstr_levmar(pb.n, 0, pb.m, 1, pb.vmask.data(), cams, kCnp, kPnp, pb.x.data(),
                                           nullptr, kMnp, synth::proj_motstr, synth::projac_motstr, &pb, 150,
                                           verbose, opts, r.info);
      break;
    case Mode::Mot:
      r.ret = c.expert ? sba_mot_levmar_x(pb.n, pb.m, 0, pb.vmask.data(), cams, kCnp, pb.x.data(), nullptr, kMnp,
                                          synth::func_mot, synth::fjac_mot, &pb, 150, verbose, opts, r.info)
                       : sba_mot_levmar(pb.n, pb.m, 0, pb.vmask.data(), cams, kCnp, pb.x.data(), nullptr, kMnp,
                                        synth::proj_mot, synth::projac_mot, &pb, 150, verbose, opts, r.info);
      break;
    case Mode::Str:
      r.ret = c.expert ? sba_str_levmar_x(pb.n, 0, pb.m, pb.vmask.data(), pts, kPnp, pb.x.data(), nullptr, kMnp,
                                          synth::func_str, synth::fjac_str, &pb, 150, verbose, opts, r.info)
                       : sba_str_levmar(pb.n, 0, pb.m, pb.vmask.data(), pts, kPnp, pb.x.data(), nullptr, kMnp,
                                        synth::proj_str, synth::projac_str, &pb, 150, verbose, opts, r.info);
      break;
  }
  *out = testing::internal::GetCapturedStdout();
  return r;
}

// The damping term of every "damping term ..." line of 1.6's verbose output.
std::vector<std::string> damping_terms(const std::string &out) {
  std::vector<std::string> terms;
  const std::string key = "\ndamping term ";
  for (size_t at = out.find(key); at != std::string::npos; at = out.find(key, at + 1)) {
    size_t b = at + key.size();
    while (out[b] == ' ') ++b;
    terms.push_back(out.substr(b, out.find(',', b) - b));
  }
  return terms;
}

void PrintTo(const Sba16Retries &c, std::ostream *os) { *os << c.initial_line << (c.expert ? ", expert" : ", simple"); }

class Retries : public ::testing::TestWithParam<Sba16Retries> {};

TEST_P(Retries, DampAsSba16Does) {
  const Sba16Retries &c = GetParam();
  std::string out;
  const Result r = run_retry_case(c, 2, &out);
  ASSERT_GT(r.ret, 0) << out;
  // 1.6's lines: the initial error, then per trial point the mean reprojection error and the
  // damping line, and nothing else.
  EXPECT_EQ(out.substr(0, out.find('\n')), c.initial_line);
  EXPECT_NE(out.find("\nmean reprojection error "), std::string::npos);
  EXPECT_EQ(out.find("SBA: "), std::string::npos) << "the library's own lines only go to a log sink";
  const std::vector<std::string> terms = damping_terms(out);
  ASSERT_GE(terms.size(), c.damping.size()) << out;
  for (size_t k = 0; k < c.damping.size(); ++k) EXPECT_EQ(terms[k], c.damping[k]) << "trial point " << k + 1;
  // The whole run: 1.6's minimum, its iterations within [x/1.25 - 3, 1.25 x + 3], its reason
  // (2 and 4 stand for each other: which ends a converged run is rounding), its counts within
  // 35%.
  EXPECT_NEAR(r.info[1], c.error, 1e-6 * c.error);
  EXPECT_GE(r.info[5], c.iterations / 1.25 - 3);
  EXPECT_LE(r.info[5], 1.25 * c.iterations + 3);
  EXPECT_TRUE(r.info[6] == 2 || r.info[6] == 4) << r.info[6];
  EXPECT_LE(std::fabs(r.info[7] - c.nfev), 0.35 * c.nfev) << r.info[7];
  EXPECT_LE(std::fabs(r.info[8] - c.njev), 0.35 * c.njev) << r.info[8];
  EXPECT_LE(std::fabs(r.info[9] - c.nlin), 0.35 * c.nlin) << r.info[9];
}

INSTANTIATE_TEST_SUITE_P(Drivers, Retries, ::testing::ValuesIn(kRetries),
                         [](const ::testing::TestParamInfo<Sba16Retries> &p) {
                           const char *mode = p.param.mode == Mode::MotStr ? "motstr"
                                              : p.param.mode == Mode::Mot  ? "mot"
                                                                           : "str";
                           return std::string(mode) + (p.param.expert ? "_expert" : "_simple");
                         });

// verbose 1: 1.6's one line on stdout, nothing per iteration.
TEST(Drivers, VerboseOnePrintsSba16sInitialLine) {
  std::string out;
  const Result r = run_retry_case(kRetries[0], 1, &out);
  ASSERT_GT(r.ret, 0);
  EXPECT_EQ(out, std::string(kRetries[0].initial_line) + "\n");
  run_retry_case(kRetries[0], 0, &out);
  EXPECT_EQ(out, "");
}

// ---------------------------------------------------------------- re-entrancy

TEST(Drivers, FourConcurrentSolvesMatchASequentialOne) {
  synth::Problem pb = synth::make(150, 8, 0.4, 0.05, 22);
  Result ref = motstr_x(pb);
  ASSERT_GT(ref.ret, 0);
  std::vector<Result> runs(4);
  std::vector<std::thread> th;
  for (int t = 0; t < 4; ++t)
    th.emplace_back([&, t] { runs[t] = t % 2 ? motstr_x(pb) : motstr_simple(pb); });
  for (auto &t : th) t.join();
  for (int t = 0; t < 4; ++t) {
    EXPECT_EQ(runs[t].ret, ref.ret);
    EXPECT_EQ(runs[t].p, ref.p) << "thread " << t;
    // The simple driver counts proj/projac calls: nvis per func/fjac call.
    const double calls = t % 2 ? 1.0 : pb.nvis;
    for (int q = 0; q < SBA_INFOSZ; ++q)
      EXPECT_EQ(runs[t].info[q], ref.info[q] * (q == 7 || q == 8 ? calls : 1.0)) << q;
  }
}

}  // namespace

// ---------------------------------------------------------------- extension options at their limits

#include <climits>
#include <cstdlib>

#include "sba_ext.h"

namespace {

struct ExtRun {
  int ret = 0;
  sba_ext_result res{};
  std::vector<double> p;
  double info[SBA_INFOSZ] = {};
  std::string log;  // "<level> <line>\n" per message
};

void capture_log(void *ctx, int level, const char *line) {
  *static_cast<std::string *>(ctx) += std::to_string(level) + " " + line + "\n";
}

// sba_motstr_levmar_x_ext on pb with ext as `tune` leaves it (log and result already set).
template <class Tune>
ExtRun run_ext(synth::Problem &pb, int verbose, Tune tune, const double *opts = nullptr, int itmax = 100) {
  ExtRun r;
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  sba_ext_result_init(&r.res);
  ext.result = &r.res;
  ext.log = capture_log;
  ext.log_ctx = &r.log;
  tune(ext);
  r.p = pb.p0;
  r.ret = sba_motstr_levmar_x_ext(pb.n, 0, pb.m, 1, pb.vmask.data(), r.p.data(), kCnp, kPnp, pb.x.data(),
                                  nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb, itmax,
                                  verbose, opts, r.info, &ext);
  return r;
}

ExtRun run_threads(synth::Problem &pb, int nthreads, int verbose = 0) {
  return run_ext(pb, verbose, [&](sba_ext_options &e) { e.nthreads = nthreads; });
}

// What a count that is asked for becomes (sba_ext.h): at most 4 per hardware thread and one
// per 64 projections.
int capped(int nvis) {
  const int hw = std::max(1, int(std::thread::hardware_concurrency()));
  return std::min(4 * hw, std::max(1, nvis / 64));
}

// INT_MAX threads used to start threads until the system refused (seconds and gigabytes for
// a problem solved in milliseconds), and the result reported INT_MAX.
TEST(Threads, AnAbsurdCountIsCappedReportedAndGivesTheSameResult) {
  unsetenv("SBA_NUM_THREADS");
  synth::Problem pb = synth::make(200, 6, 0.5, 0.05, 61);
  ASSERT_GT(capped(pb.nvis), 1);
  const ExtRun one = run_threads(pb, 1);
  ASSERT_GT(one.ret, 0);
  EXPECT_EQ(one.res.nthreads, 1);
  for (int t : {INT_MAX, 5000, 3}) {
    const ExtRun r = run_threads(pb, t);
    EXPECT_EQ(r.res.nthreads, std::min(t, capped(pb.nvis))) << t;
    EXPECT_EQ(r.ret, one.ret) << t;
    EXPECT_EQ(r.p, one.p) << t;
    for (int q = 0; q < SBA_INFOSZ; ++q) EXPECT_EQ(r.info[q], one.info[q]) << t << ": info[" << q << "]";
  }
  // A problem too small to share: one thread, whatever is asked.
  synth::Problem tiny = synth::make(12, 3, 0.5, 0.05, 62);
  ASSERT_LT(tiny.nvis, 64);
  EXPECT_EQ(run_threads(tiny, 16).res.nthreads, 1);
}

// SBA_NUM_THREADS is read as a whole positive decimal integer; a huge one is a large request
// (capped), never a wrapped int; anything else is ignored, with a warning.
TEST(Threads, SbaNumThreadsIsParsedWithRangeChecks) {
  synth::Problem pb = synth::make(200, 6, 0.5, 0.05, 61);
  const int cap = capped(pb.nvis), automatic = 1;  // under 10,000 projections: one thread
  struct Case {
    const char *value;
    int want;
    bool warned;
  };
  const Case cases[] = {{"2", 2, false},
                        {"5000", cap, false},
                        {"99999999999", cap, false},
                        {"999999999999999999999999999", cap, false},
                        {"12abc", automatic, true},
                        {"abc", automatic, true},
                        {"-3", automatic, true},
                        {"0", automatic, true},
                        {"3 ", automatic, true}};
  for (const Case &c : cases) {
    SCOPED_TRACE(std::string("SBA_NUM_THREADS=\"") + c.value + "\"");
    ASSERT_EQ(setenv("SBA_NUM_THREADS", c.value, 1), 0);
    const ExtRun r = run_threads(pb, 0, 1);
    EXPECT_GT(r.ret, 0);
    EXPECT_EQ(r.res.nthreads, c.want);
    const std::string warning = std::string("1 sba_motstr_levmar_x: SBA_NUM_THREADS=\"") + c.value +
                                "\" is not a positive integer: ignored";
    EXPECT_EQ(r.log.find(warning) != std::string::npos, c.warned) << r.log;
    // Not verbose: the same count, and the same warning (and nothing else).
    const ExtRun quiet = run_threads(pb, 0, 0);
    EXPECT_EQ(quiet.res.nthreads, c.want);
    EXPECT_EQ(quiet.log, c.warned ? warning + " (the library chooses the thread count)\n" : "");
  }
  unsetenv("SBA_NUM_THREADS");
}

}  // namespace

namespace {

// opts[0] = tau: 1.6 uses |tau|, so a negative one works; 0 (or -0) made the initial damping 0,
// which no failed step can grow, and the solve "succeeded" with nothing refined (reason 6).
TEST(Tau, ZeroIsRefusedANegativeOneIsItsMagnitude) {
  synth::Problem pb = synth::make(60, 5, 0.5, 0.05, 63);
  const auto plain = [](sba_ext_options &) {};
  for (double tau : {0.0, -0.0}) {
    const double opts[SBA_OPTSSZ] = {tau, 1e-12, 1e-12, 1e-12, 0.0};
    const ExtRun r = run_ext(pb, 0, plain, opts);
    EXPECT_EQ(r.ret, SBA_ERROR);
    EXPECT_EQ(r.info[6], 0);
    EXPECT_EQ(r.p, pb.p0);
    EXPECT_EQ(r.log, "0 sba_motstr_levmar_x: opts[0] (tau: the initial damping is |tau| * max diag(J^T J)) "
                     "must be nonzero\n");
  }
  const double neg[SBA_OPTSSZ] = {-1e-3, 1e-12, 1e-12, 1e-12, 0.0};
  const double pos[SBA_OPTSSZ] = {1e-3, 1e-12, 1e-12, 1e-12, 0.0};
  const ExtRun a = run_ext(pb, 0, plain, neg), b = run_ext(pb, 0, plain, pos);
  ASSERT_GT(a.ret, 0);
  EXPECT_EQ(a.p, b.p);
  for (int q = 0; q < SBA_INFOSZ; ++q) EXPECT_EQ(a.info[q], b.info[q]) << q;
}

// A tau so small that tau * max diag(J^T J) underflows to 0: the damping is floored (at 2^-400
// max diag(J^T J), see sba_ext.h) and the solve refines p as usual; it used to stop at once
// with reason 6, no damping being able to grow from 0.
TEST(Tau, ADampingThatUnderflowsIsFlooredAndTheSolveRefines) {
  synth::Problem pb = synth::make(60, 5, 0.5, 0.05, 64);
  // Measurement covariances of 1e8 px^2 make the weighted J^T J tiny (diagonal ~1e-2).
  std::vector<double> covx(size_t(pb.nvis) * 4, 0.0);
  for (int k = 0; k < pb.nvis; ++k) covx[4 * size_t(k)] = covx[4 * size_t(k) + 3] = 1e8;
  ASSERT_EQ(4.9e-324 * 1e-2, 0.0);
  auto run = [&](double tau, double info[SBA_INFOSZ]) {
    const double opts[SBA_OPTSSZ] = {tau, 1e-12, 1e-12, 1e-12, 0.0};
    std::vector<double> p = pb.p0;
    return sba_motstr_levmar_x(pb.n, 0, pb.m, 1, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(),
                               covx.data(), kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 100, 0,
                               opts, info);
  };
  double ref[SBA_INFOSZ], info[SBA_INFOSZ];
  ASSERT_GT(run(1e-3, ref), 1);
  const int ret = run(4.9e-324, info);
  ASSERT_GT(ret, 1);
  EXPECT_GE(info[6], 1);
  EXPECT_LE(info[6], 5);
  EXPECT_LT(info[1], 0.05 * info[0]);  // the start is off by far more than the noise
  EXPECT_NEAR(info[1], ref[1], 1e-6 * ref[1]);  // the minimum the default tau finds
}

// The progress callback runs after every iteration, including the one that ends the solve;
// what it returns after the last one changes nothing.
struct Calls {
  int calls = 0, stop_from = 1 << 30;
  std::vector<int> iterations;
};
int count_progress(void *ctx, const sba_progress *s) {
  Calls &c = *static_cast<Calls *>(ctx);
  ++c.calls;
  c.iterations.push_back(s->iteration);
  return s->iteration >= c.stop_from;
}

TEST(Progress, CalledAfterEveryIterationIncludingTheLast) {
  synth::Problem pb = synth::make(80, 5, 0.5, 0.05, 65);
  // A solve that ends by a stop test (reason 1, 2, 4 or 5).
  Calls full;
  const ExtRun r = run_ext(pb, 0, [&](sba_ext_options &e) {
    e.progress = count_progress;
    e.progress_ctx = &full;
  });
  ASSERT_GT(r.ret, 2);
  ASSERT_NE(r.info[6], 3);
  EXPECT_EQ(full.calls, r.ret);
  EXPECT_EQ(full.calls, int(r.info[5]));
  for (int k = 0; k < full.calls; ++k) EXPECT_EQ(full.iterations[size_t(k)], k + 1);
  // Ending by itmax, with the callback asking to stop after the last iteration only: reason 3.
  for (int itmax : {1, 4}) {
    Calls last;
    last.stop_from = itmax;
    const ExtRun s = run_ext(
        pb, 0,
        [&](sba_ext_options &e) {
          e.progress = count_progress;
          e.progress_ctx = &last;
        },
        nullptr, itmax);
    EXPECT_EQ(s.ret, itmax);
    EXPECT_EQ(s.info[6], 3) << "itmax " << itmax;
    EXPECT_EQ(last.calls, itmax);
  }
  // Asking earlier still stops: reason 9 after that iteration.
  Calls early;
  early.stop_from = 2;
  const ExtRun e = run_ext(pb, 0, [&](sba_ext_options &o) {
    o.progress = count_progress;
    o.progress_ctx = &early;
  });
  EXPECT_EQ(e.ret, 2);
  EXPECT_EQ(e.info[6], SBA_STOP_USER);
  EXPECT_EQ(early.calls, 2);
}

// An unknown SBA_LINSOLVER does not stop an unmodified 1.6 program, so it is not an error of
// the call: a warning (level 1), shown verbose or not (the program's user set it, and needs
// to know it is ignored). This call gives options, so the default it falls back to is auto,
// which picks chol for a problem this small.
TEST(Drivers, UnknownSbaLinsolverIsAWarning) {
  synth::Problem pb = synth::make(40, 4, 0.5, 0.05, 66);
  ASSERT_EQ(setenv("SBA_LINSOLVER", "chlo", 1), 0);
  const auto plain = [](sba_ext_options &) {};
  const ExtRun loud = run_ext(pb, 1, plain), quiet = run_ext(pb, 0, plain);
  unsetenv("SBA_LINSOLVER");
  EXPECT_GT(loud.ret, 0);
  EXPECT_EQ(loud.res.linsolver, std::string("chol"));
  EXPECT_NE(loud.log.find("1 sba_motstr_levmar_x: unknown SBA_LINSOLVER \"chlo\""), std::string::npos)
      << loud.log;
  // No error-level line. Each line starts with its level; a figure ending in 0 elsewhere in
  // a line (the MiB available, say) is not one.
  EXPECT_EQ(loud.log.rfind("0 ", 0), std::string::npos) << loud.log;
  EXPECT_EQ(loud.log.find("\n0 "), std::string::npos) << loud.log;
  EXPECT_GT(quiet.ret, 0);
  EXPECT_EQ(quiet.log, "1 sba_motstr_levmar_x: unknown SBA_LINSOLVER \"chlo\" (known: " +
                           std::string(sba_linsolver_names()) + "); using auto\n");
}

// With every point held (or in the motion-only driver) the system is block diagonal: one small
// Cholesky per camera runs whatever solver was asked, and the result and the verbose line say
// so, not the solver asked for or auto's choice of one.
TEST(Drivers, ABlockDiagonalSystemReportsWhatRan) {
  synth::Problem pb = synth::make(40, 4, 0.5, 0.05, 66);
  for (const char *asked : {"auto", "svd", "sparse-chol"}) {
    SCOPED_TRACE(asked);
    sba_ext_options ext;
    sba_ext_options_init(&ext);
    sba_ext_result res;
    sba_ext_result_init(&res);
    std::string log;
    ext.result = &res;
    ext.log = capture_log;
    ext.log_ctx = &log;
    ext.linsolver = asked;
    std::vector<double> p = pb.p0;
    double info[SBA_INFOSZ];
    const int ret = sba_motstr_levmar_x_ext(pb.n, pb.n, pb.m, 1, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(),
                                            nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 20, 1, nullptr,
                                            info, &ext);
    EXPECT_GT(ret, 0) << log;
    EXPECT_STREQ(res.linsolver, "block-diagonal");
    EXPECT_NE(log.find("2 sba_motstr_levmar_x: linear solver: block-diagonal, " + std::string(asked) +
                       " asked (no free points: each camera's step is solved alone)\n"),
              std::string::npos)
        << log;
    EXPECT_EQ(log.find("S of 0 unknowns"), std::string::npos) << log;
    p.assign(pb.p0.begin(), pb.p0.begin() + pb.m * kCnp);
    pb.fixed_points = pb.truth.data() + pb.m * kCnp;
    sba_ext_result_init(&res);
    EXPECT_GT(sba_mot_levmar_x_ext(pb.n, pb.m, 1, pb.vmask.data(), p.data(), kCnp, pb.x.data(), nullptr, kMnp,
                                   synth::func_mot, synth::fjac_mot, &pb, 20, 0, nullptr, info, &ext),
              0);
    EXPECT_STREQ(res.linsolver, "block-diagonal");
  }
  EXPECT_EQ(sba_linsolver_valid("block-diagonal"), 0);
}

}  // namespace

namespace {

// The solver names come from one table: the list the C API hands out and the check agree.
TEST(LinsolverNames, ListAndValidityCheckAgree) {
  EXPECT_STREQ(sba_linsolver_names(),
               "chol ldlt bk lu qr qrnoq svd cg ldl-amd sparse-chol chol-lapack iterative-schur auto");
  std::string names = sba_linsolver_names(), name;
  int count = 0;
  for (size_t k = 0; k <= names.size(); ++k)
    if (k == names.size() || names[k] == ' ') {
      EXPECT_EQ(sba_linsolver_valid(name.c_str()), 1) << name;
      name.clear();
      ++count;
    } else {
      name += names[k];
    }
  EXPECT_EQ(count, 13);
  for (const char *bad : {"", "CHOL", "chol ", " chol", "ldl", "sparse", "nope"})
    EXPECT_EQ(sba_linsolver_valid(bad), 0) << "'" << bad << "'";
  EXPECT_EQ(sba_linsolver_valid(nullptr), 0);
}

}  // namespace
