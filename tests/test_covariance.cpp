// SPDX-License-Identifier: BSD-3-Clause
// Covariance of the solution (sba_motstr_covariance[_x]): against a brute-force
// sigma^2 (J^T J)^-1 on small problems, against the spread of solutions over noisy
// replicates, and the gauge handling; and the stages of src/covariance.cpp on their own
// (linked from the library's objects).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "camera_unknowns.h"
#include "covariance.h"
#include "layout.h"
#include "sba_ext.h"
#include "synth.h"

namespace {

using synth::kCnp;
using synth::kMnp;
using synth::kPnp;

// The index the drivers build, for calling the expert callbacks directly.
struct Index {
  std::vector<int> rowptr, colidx, val;
  sba_crsm crsm{};
  explicit Index(const synth::Problem &pb) {
    int k = 0;
    for (int i = 0; i < pb.n; ++i) {
      rowptr.push_back(k);
      for (int j = 0; j < pb.m; ++j)
        if (pb.vmask[size_t(i) * pb.m + j]) colidx.push_back(j), val.push_back(k++);
    }
    rowptr.push_back(k);
    crsm = {pb.n, pb.m, k, val.data(), colidx.data(), rowptr.data()};
  }
};

int solve(synth::Problem &pb, std::vector<double> &p, int mcon) {
  return sba_motstr_levmar_x(pb.n, 0, pb.m, mcon, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(),
                             nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 200, 0,
                             nullptr, nullptr);
}

struct Cov {
  int ret = 0;
  sba_covariance_request req{};
  std::vector<int> cams, pts;
  std::vector<double> camcov, ptcov;
};

Cov covariance(synth::Problem &pb, std::vector<double> &p, int mcon, int ncon, bool simple = false,
               bool analytic = true, int unscaled = 0, size_t size = sizeof(sba_covariance_request),
               double point_damping = 0) {
  Cov c;
  for (int j = 0; j < pb.m; ++j) c.cams.push_back(j);
  for (int i = 0; i < pb.n; ++i) c.pts.push_back(i);
  c.camcov.resize(size_t(pb.m) * kCnp * kCnp);
  c.ptcov.resize(size_t(pb.n) * kPnp * kPnp);
  sba_covariance_request_init(&c.req);
  c.req.ncams = pb.m;
  c.req.cams = c.cams.data();
  c.req.camcov = c.camcov.data();
  c.req.npts = pb.n;
  c.req.pts = c.pts.data();
  c.req.ptcov = c.ptcov.data();
  c.req.unscaled = unscaled;
  c.req.point_damping = point_damping;
  c.req.size = size;
  if (simple)
    c.ret = sba_motstr_covariance(pb.n, ncon, pb.m, mcon, pb.vmask.data(), p.data(), kCnp, kPnp,
                                  pb.x.data(), nullptr, kMnp, synth::proj_motstr,
                                  analytic ? synth::projac_motstr : nullptr, &pb, &c.req, nullptr);
  else
    c.ret = sba_motstr_covariance_x(pb.n, ncon, pb.m, mcon, pb.vmask.data(), p.data(), kCnp, kPnp,
                                    pb.x.data(), nullptr, kMnp, synth::func_motstr,
                                    analytic ? synth::fjac_motstr : nullptr, &pb, &c.req, nullptr);
  return c;
}

// sigma^2 (J^T J)^-1 over the free parameters, formed densely.
std::vector<double> brute_force(synth::Problem &pb, std::vector<double> &p, int mcon, int ncon,
                                int *nfree_out) {
  Index idx(pb);
  const int nvis = idx.crsm.nnz, jb = kMnp * (kCnp + kPnp);
  std::vector<double> jac(size_t(nvis) * jb), hx(size_t(nvis) * kMnp);
  synth::fjac_motstr(p.data(), &idx.crsm, nullptr, nullptr, jac.data(), &pb);
  synth::func_motstr(p.data(), &idx.crsm, nullptr, nullptr, hx.data(), &pb);
  const int nfc = pb.m - mcon, nfp = pb.n - ncon, nfree = nfc * kCnp + nfp * kPnp;
  std::vector<double> J(size_t(nvis) * kMnp * nfree, 0.0);
  for (int i = 0; i < pb.n; ++i)
    for (int k = idx.rowptr[i]; k < idx.rowptr[i + 1]; ++k) {
      const int j = idx.colidx[k];
      for (int r = 0; r < kMnp; ++r) {
        double *row = J.data() + size_t(k * kMnp + r) * nfree;
        if (j >= mcon)
          for (int a = 0; a < kCnp; ++a) row[(j - mcon) * kCnp + a] = jac[size_t(k) * jb + r * kCnp + a];
        if (i >= ncon)
          for (int a = 0; a < kPnp; ++a)
            row[nfc * kCnp + (i - ncon) * kPnp + a] = jac[size_t(k) * jb + kMnp * kCnp + r * kPnp + a];
      }
    }
  std::vector<double> JtJ(size_t(nfree) * nfree, 0.0);
  for (int r = 0; r < nvis * kMnp; ++r)
    for (int a = 0; a < nfree; ++a) {
      const double v = J[size_t(r) * nfree + a];
      if (v == 0.0) continue;
      for (int b = 0; b < nfree; ++b) JtJ[size_t(a) * nfree + b] += v * J[size_t(r) * nfree + b];
    }
  EXPECT_EQ(sba_symat_invert_Chol(JtJ.data(), nfree), 1);
  // The inverse is in the lower triangle; mirror it for the comparisons below.
  for (int a = 0; a < nfree; ++a)
    for (int b = a + 1; b < nfree; ++b) JtJ[size_t(a) * nfree + b] = JtJ[size_t(b) * nfree + a];
  double e2 = 0;
  for (int q = 0; q < nvis * kMnp; ++q) e2 += (pb.x[size_t(q)] - hx[size_t(q)]) * (pb.x[size_t(q)] - hx[size_t(q)]);
  const double sigma2 = e2 / (nvis * kMnp - nfree);
  for (double &v : JtJ) v *= sigma2;
  *nfree_out = nfree;
  return JtJ;
}

TEST(Covariance, MatchesBruteForceInverseWhenTheGaugeIsFixed) {
  synth::Problem pb = synth::make(25, 5, 0.5, 0.05, 51);
  std::vector<double> p = pb.p0;
  const int mcon = 2, ncon = 3;  // two fixed cameras fix rotation, translation and scale
  ASSERT_GT(solve(pb, p, mcon), 0);
  int nfree = 0;
  const std::vector<double> ref = brute_force(pb, p, mcon, ncon, &nfree);
  for (bool simple : {false, true}) {
    Cov c = covariance(pb, p, mcon, ncon, simple);
    ASSERT_EQ(c.ret, 0);
    EXPECT_EQ(c.req.nfree, nfree);
    EXPECT_EQ(c.req.rank, nfree);
    const int nfc = pb.m - mcon;
    double worst = 0;
    for (int j = 0; j < pb.m; ++j)
      for (int a = 0; a < kCnp; ++a)
        for (int b = 0; b < kCnp; ++b) {
          const double got = c.camcov[size_t(j) * kCnp * kCnp + a * kCnp + b];
          if (j < mcon) {
            EXPECT_EQ(got, 0.0);
            continue;
          }
          const int ra = (j - mcon) * kCnp + a, rb = (j - mcon) * kCnp + b;
          const double want = ref[size_t(ra) * nfree + rb];
          const double scale = std::sqrt(ref[size_t(ra) * nfree + ra] * ref[size_t(rb) * nfree + rb]);
          worst = std::max(worst, std::fabs(got - want) / scale);
        }
    for (int i = 0; i < pb.n; ++i)
      for (int a = 0; a < kPnp; ++a)
        for (int b = 0; b < kPnp; ++b) {
          const double got = c.ptcov[size_t(i) * kPnp * kPnp + a * kPnp + b];
          if (i < ncon) {
            EXPECT_EQ(got, 0.0);
            continue;
          }
          const int ra = nfc * kCnp + (i - ncon) * kPnp + a, rb = nfc * kCnp + (i - ncon) * kPnp + b;
          const double want = ref[size_t(ra) * nfree + rb];
          const double scale = std::sqrt(ref[size_t(ra) * nfree + ra] * ref[size_t(rb) * nfree + rb]);
          worst = std::max(worst, std::fabs(got - want) / scale);
        }
    EXPECT_LT(worst, 1e-8) << (simple ? "simple" : "expert");
  }
}

// unscaled gives the blocks of (J^T J)^-1, the scaled ones over sigma2, sigma2 still returned;
// a request of the size before the field (an older caller's) gets the scaled ones.
TEST(Covariance, UnscaledBlocksAreTheScaledOverSigma2) {
  synth::Problem pb = synth::make(25, 5, 0.5, 0.05, 51);
  std::vector<double> p = pb.p0;
  ASSERT_GT(solve(pb, p, 2), 0);
  const Cov scaled = covariance(pb, p, 2, 3);
  const Cov unscaled = covariance(pb, p, 2, 3, false, true, 1);
  const Cov older = covariance(pb, p, 2, 3, false, true, 1, offsetof(sba_covariance_request, unscaled));
  ASSERT_EQ(scaled.ret, 0);
  ASSERT_EQ(unscaled.ret, 0);
  ASSERT_EQ(older.ret, 0);
  ASSERT_GT(scaled.req.sigma2, 0.0);
  EXPECT_EQ(unscaled.req.sigma2, scaled.req.sigma2);
  EXPECT_EQ(older.camcov, scaled.camcov);
  EXPECT_EQ(older.ptcov, scaled.ptcov);
  for (size_t k = 0; k < scaled.camcov.size(); ++k)
    EXPECT_NEAR(unscaled.camcov[k] * scaled.req.sigma2, scaled.camcov[k], 1e-12 * std::fabs(scaled.camcov[k])) << k;
  for (size_t k = 0; k < scaled.ptcov.size(); ++k)
    EXPECT_NEAR(unscaled.ptcov[k] * scaled.req.sigma2, scaled.ptcov[k], 1e-12 * std::fabs(scaled.ptcov[k])) << k;
}

// point_damping adds d I to every point's V_i: J^T J grows by a positive semi-definite term,
// so no variance grows and the points' shrink; 0 is no damping at all, to the bit; a negative
// or non-finite one is refused.
TEST(Covariance, PointDampingShrinksTheVariances) {
  synth::Problem pb = synth::make(25, 5, 0.5, 0.05, 51);
  std::vector<double> p = pb.p0;
  ASSERT_GT(solve(pb, p, 2), 0);
  const size_t full = sizeof(sba_covariance_request);
  const Cov plain = covariance(pb, p, 2, 3, false, true, 1);
  const Cov zero = covariance(pb, p, 2, 3, false, true, 1, full, 0.0);
  const Cov damped = covariance(pb, p, 2, 3, false, true, 1, full, 1e3);
  ASSERT_EQ(damped.ret, 0);
  EXPECT_EQ(zero.camcov, plain.camcov);
  EXPECT_EQ(zero.ptcov, plain.ptcov);
  for (int j = 2; j < pb.m; ++j)
    for (int a = 0; a < kCnp; ++a) {
      const size_t k = size_t(j) * kCnp * kCnp + size_t(a) * (kCnp + 1);
      EXPECT_LE(damped.camcov[k], plain.camcov[k] * (1 + 1e-12)) << j << " " << a;
    }
  for (int i = 3; i < pb.n; ++i)
    for (int a = 0; a < kPnp; ++a) {
      const size_t k = size_t(i) * kPnp * kPnp + size_t(a) * (kPnp + 1);
      EXPECT_LT(damped.ptcov[k], plain.ptcov[k]) << i << " " << a;
    }
  testing::internal::CaptureStderr();
  for (double bad : {-1e-8, std::nan(""), HUGE_VAL})
    EXPECT_EQ(covariance(pb, p, 2, 3, false, true, 1, full, bad).ret, SBA_ERROR) << bad;
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("req->point_damping must be finite and >= 0"), std::string::npos) << err;
}

TEST(Covariance, AFreeGaugeGivesAPseudoInverseAndItsRank) {
  synth::Problem pb = synth::make(40, 5, 0.5, 0.05, 52);
  std::vector<double> p = pb.p0;
  ASSERT_GT(solve(pb, p, 0), 0);
  Cov c = covariance(pb, p, 0, 0);
  ASSERT_EQ(c.ret, 0);
  // Rotation, translation and scale of the whole scene are not determined.
  EXPECT_EQ(c.req.rank, c.req.nfree - 7);
  for (double v : c.camcov) ASSERT_TRUE(std::isfinite(v));
  for (int j = 0; j < pb.m; ++j)
    for (int a = 0; a < kCnp; ++a) EXPECT_GT(c.camcov[size_t(j) * kCnp * kCnp + a * (kCnp + 1)], 0.0);
}

TEST(Covariance, FiniteDifferenceJacobianGivesNearlyTheSameBlocks) {
  synth::Problem pb = synth::make(25, 5, 0.5, 0.05, 51);
  std::vector<double> p = pb.p0;
  ASSERT_GT(solve(pb, p, 2), 0);
  const Cov an = covariance(pb, p, 2, 0), fd = covariance(pb, p, 2, 0, false, false);
  ASSERT_EQ(fd.ret, 0);
  EXPECT_EQ(fd.req.rank, an.req.rank);
  EXPECT_NEAR(fd.req.sigma2 / an.req.sigma2, 1.0, 1e-9);
  // Forward differences are accurate to about 1e-4 relative here.
  for (int j = 2; j < pb.m; ++j)
    for (int a = 0; a < kCnp; ++a) {
      const size_t d = size_t(j) * kCnp * kCnp + a * (kCnp + 1);
      EXPECT_NEAR(fd.camcov[d] / an.camcov[d], 1.0, 1e-3) << j << "," << a;
    }
}

// The predicted covariance describes how the solution scatters when the noise is drawn again.
TEST(Covariance, PredictsTheSpreadOfSolutionsOverNoisyReplicates) {
  const double sigma = 0.5;
  synth::Problem pb = synth::make(40, 5, 0.0, 0.0, 53);  // exact projections of the truth
  const std::vector<double> exact = pb.x;
  const int mcon = 2, cam = 3, pt = 11;
  std::mt19937_64 rng(99);
  std::normal_distribution<double> N(0.0, sigma);
  const int reps = 400;
  std::vector<double> mean(kCnp + kPnp, 0.0), sq((kCnp + kPnp) * (kCnp + kPnp), 0.0);
  std::vector<double> predicted_cam(kCnp * kCnp, 0.0), predicted_pt(kPnp * kPnp, 0.0);
  for (int r = 0; r < reps; ++r) {
    for (size_t q = 0; q < pb.x.size(); ++q) pb.x[q] = exact[q] + N(rng);
    std::vector<double> p = pb.truth;
    ASSERT_GT(solve(pb, p, mcon), 0);
    double v[kCnp + kPnp];
    for (int a = 0; a < kCnp; ++a) v[a] = p[size_t(cam) * kCnp + a];
    for (int a = 0; a < kPnp; ++a) v[kCnp + a] = p[size_t(pb.m) * kCnp + pt * kPnp + a];
    for (int a = 0; a < kCnp + kPnp; ++a) {
      mean[a] += v[a];
      for (int b = 0; b < kCnp + kPnp; ++b) sq[a * (kCnp + kPnp) + b] += v[a] * v[b];
    }
    if (r < 20) {  // the prediction varies little between replicates; average a few
      Cov c = covariance(pb, p, mcon, 0);
      ASSERT_EQ(c.ret, 0);
      for (int q = 0; q < kCnp * kCnp; ++q) predicted_cam[q] += c.camcov[size_t(cam) * kCnp * kCnp + q] / 20;
      for (int q = 0; q < kPnp * kPnp; ++q) predicted_pt[q] += c.ptcov[size_t(pt) * kPnp * kPnp + q] / 20;
    }
  }
  // 400 replicates: the sample variances are within about 3 x sqrt(2/400) = 21% of the truth.
  for (int a = 0; a < kCnp + kPnp; ++a) {
    const double m = mean[a] / reps;
    const double var = sq[a * (kCnp + kPnp) + a] / reps - m * m;
    const double pred = a < kCnp ? predicted_cam[a * (kCnp + 1)] : predicted_pt[(a - kCnp) * (kPnp + 1)];
    EXPECT_GT(var / pred, 0.75) << "parameter " << a;
    EXPECT_LT(var / pred, 1.3) << "parameter " << a;
  }
}

TEST(Covariance, BadRequestsAreRefused) {
  synth::Problem pb = synth::make(20, 4, 0.5, 0.05, 54);
  std::vector<double> p = pb.p0;
  Cov c = covariance(pb, p, 2, 0);
  ASSERT_EQ(c.ret, 0);
  const int bad_cam = 7;
  c.req.cams = &bad_cam;
  c.req.ncams = 1;
  testing::internal::CaptureStderr();
  EXPECT_EQ(sba_motstr_covariance_x(pb.n, 0, pb.m, 2, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(),
                                    nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb, &c.req,
                                    nullptr),
            SBA_ERROR);
  EXPECT_EQ(sba_motstr_covariance_x(pb.n, 0, pb.m, 2, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(),
                                    nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb, nullptr,
                                    nullptr),
            SBA_ERROR);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("req->cams[0] is not a camera index"), std::string::npos) << err;
  EXPECT_NE(err.find("req is NULL"), std::string::npos) << err;
}

// The cancel callback: polled at every stage, it stops the computation wherever it says so,
// with SBA_ERROR and one line; never saying so changes nothing; the drivers never poll it.
struct CancelAt {
  int polls = 0, stop_at = 0;  // 0: never stop
  std::string errors;
  static int poll(void *ctx) {
    CancelAt &c = *static_cast<CancelAt *>(ctx);
    return ++c.polls == c.stop_at;
  }
  static void sink(void *ctx, int level, const char *line) {
    if (level == SBA_LOG_ERROR) static_cast<CancelAt *>(ctx)->errors += std::string(line) + "\n";
  }
};

TEST(Covariance, TheCancelCallbackStopsItAtItsNextPoll) {
  synth::Problem pb = synth::make(60, 6, 0.5, 0.05, 57);
  std::vector<double> p = pb.p0;
  ASSERT_GT(solve(pb, p, 1), 0);
  const Cov plain = covariance(pb, p, 1, 0);
  ASSERT_EQ(plain.ret, 0);
  auto run = [&](CancelAt &c, Cov &out) {
    out = plain;
    std::fill(out.camcov.begin(), out.camcov.end(), 0.0);
    std::fill(out.ptcov.begin(), out.ptcov.end(), 0.0);
    out.req.camcov = out.camcov.data();
    out.req.ptcov = out.ptcov.data();
    sba_ext_options ext;
    sba_ext_options_init(&ext);
    ext.cancel = CancelAt::poll;
    ext.cancel_ctx = &c;
    ext.log = CancelAt::sink;
    ext.log_ctx = &c;
    return sba_motstr_covariance_x(pb.n, 0, pb.m, 1, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(), nullptr,
                                   kMnp, synth::func_motstr, synth::fjac_motstr, &pb, &out.req, &ext);
  };
  CancelAt never;
  Cov c;
  EXPECT_EQ(run(never, c), 0);
  EXPECT_EQ(c.camcov, plain.camcov);
  EXPECT_EQ(c.ptcov, plain.ptcov);
  // The start and each stage: linearized, V about to be inverted, S assembled, S decomposed
  // (the loops add polls only as time passes).
  EXPECT_GE(never.polls, 5);
  for (int k = 1; k <= 5; ++k) {
    SCOPED_TRACE(k);
    CancelAt at;
    at.stop_at = k;
    EXPECT_EQ(run(at, c), SBA_ERROR);
    EXPECT_EQ(at.polls, k);
    EXPECT_EQ(at.errors, "sba: stopped by the cancel callback\n");
  }
  CancelAt solving;
  solving.stop_at = 1;
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.cancel = CancelAt::poll;
  ext.cancel_ctx = &solving;
  std::vector<double> q = pb.p0;
  EXPECT_GT(sba_motstr_levmar_x_ext(pb.n, 0, pb.m, 1, pb.vmask.data(), q.data(), kCnp, kPnp, pb.x.data(), nullptr,
                                    kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 50, 0, nullptr, nullptr, &ext),
            0);
  EXPECT_EQ(solving.polls, 0);
}

// Keeps only the first projection of point q (in vmask and in x): q is then seen by one
// camera, and its 3 parameters meet 2 measurements.
int see_once(synth::Problem &pb, int q) {
  std::vector<double> x;
  int k = 0, camera = -1;
  for (int i = 0; i < pb.n; ++i)
    for (int j = 0; j < pb.m; ++j) {
      char &v = pb.vmask[size_t(i) * pb.m + j];
      if (!v) continue;
      const bool keep = i != q || camera < 0;
      if (i == q && keep) camera = j;
      if (keep) x.insert(x.end(), pb.x.begin() + 2 * k, pb.x.begin() + 2 * k + 2);
      else v = 0;
      ++k;
    }
  pb.x = x;
  pb.nvis = int(x.size() / 2);
  return camera;
}

// V_i of a point seen once is singular in exact arithmetic; its rounding-level pivot may come
// out positive, and a Cholesky-based inverse then "succeeds" with variances of 1e10 and more.
// Every such request must be refused, naming the point, over many problems and both callback
// kinds; never a success reporting full rank.
TEST(Covariance, APointSeenByOneCameraIsRefusedByName) {
  int refused = 0, calls = 0;
  for (unsigned seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    synth::Problem pb = synth::make(30, 5, 0.5, 0.05, 600 + seed);
    const int q = int(seed * 7) % pb.n;
    see_once(pb, q);
    std::vector<double> p = pb.p0;
    ASSERT_GT(solve(pb, p, 2), 0);
    for (bool simple : {false, true}) {
      testing::internal::CaptureStderr();
      const Cov c = covariance(pb, p, 2, 0, simple);
      const std::string err = testing::internal::GetCapturedStderr();
      ++calls;
      EXPECT_EQ(c.ret, SBA_ERROR) << (simple ? "simple" : "expert") << ": rank " << c.req.rank
                                  << " of " << c.req.nfree;
      refused += c.ret == SBA_ERROR;
      const std::string want = "point " + std::to_string(q) +
                               " is seen by one camera only: its 3 parameters are not determined "
                               "by 2 measurements (V_i has rank 2 < pnp = 3)";
      EXPECT_NE(err.find(want), std::string::npos) << err;
      EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    }
  }
  EXPECT_EQ(refused, calls);
}

// Two cameras at the same place see a point along the same ray: its depth is not determined,
// and its V_i has rank 2 although it has 4 measurements.
TEST(Covariance, APointSeenOnlyFromOneCentreIsRefusedByName) {
  synth::Problem pb = synth::make(30, 5, 0.5, 0.05, 655);
  std::vector<double> p = pb.p0;
  ASSERT_GT(solve(pb, p, 2), 0);
  std::copy(p.begin(), p.begin() + kCnp, p.begin() + kCnp);  // camera 1 := camera 0 (both fixed)
  const int q = 0;  // the first point, so that it is the one named
  for (int j = 0; j < pb.m; ++j) pb.vmask[size_t(q) * pb.m + j] = j < 2;
  // x: the exact projections of p (the residual does not matter for the rank).
  pb.x.clear();
  for (int i = 0; i < pb.n; ++i)
    for (int j = 0; j < pb.m; ++j)
      if (pb.vmask[size_t(i) * pb.m + j]) {
        double xy[2];
        synth::project(p.data() + j * kCnp, p.data() + pb.m * kCnp + i * kPnp, xy, nullptr, nullptr);
        pb.x.push_back(xy[0] + 0.3 * std::sin(double(pb.x.size())));
        pb.x.push_back(xy[1] + 0.3 * std::cos(double(pb.x.size())));
      }
  testing::internal::CaptureStderr();
  const Cov c = covariance(pb, p, 2, 0);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(c.ret, SBA_ERROR);
  EXPECT_NE(err.find("point 0 is not determined by its 2 projections"), std::string::npos) << err;
  EXPECT_NE(err.find("(V_i has rank 2 < pnp = 3)"), std::string::npos) << err;
}

}  // namespace

namespace {

// A point without a single projection has nothing at all to determine it: the message says so
// rather than counting "0 cameras only" and "0 measurements".
TEST(Covariance, APointSeenByNoCameraIsRefusedByName) {
  synth::Problem pb = synth::make(30, 5, 0.5, 0.05, 611);
  const int q = 7;
  std::vector<double> x;
  int k = 0;
  for (int i = 0; i < pb.n; ++i)
    for (int j = 0; j < pb.m; ++j) {
      char &v = pb.vmask[size_t(i) * pb.m + j];
      if (!v) continue;
      if (i == q) v = 0;
      else x.insert(x.end(), pb.x.begin() + 2 * k, pb.x.begin() + 2 * k + 2);
      ++k;
    }
  pb.x = x;
  pb.nvis = int(x.size() / 2);
  std::vector<double> p = pb.p0;
  testing::internal::CaptureStderr();
  const Cov c = covariance(pb, p, 2, 0);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(c.ret, SBA_ERROR);
  EXPECT_NE(err.find("point 7 is seen by no camera (V_i has rank 0 < pnp = 3): its covariance is unbounded"),
            std::string::npos)
      << err;
}

}  // namespace

// ---- the stages, one by one ----

namespace {

// The lines a Logger says, for the messages of a stage.
void keep_line(void *ctx, int, const char *line) { static_cast<std::vector<std::string> *>(ctx)->push_back(line); }

// Q diag(lambda) Q^T with Q the rotation about (1, 2, 2)/3 by 0.7: a symmetric 3x3 matrix of
// known eigenvalues, row-major.
std::vector<double> with_eigenvalues(const double lambda[3]) {
  const double u[3] = {1.0 / 3, 2.0 / 3, 2.0 / 3}, c = std::cos(0.7), s = std::sin(0.7);
  double Q[9];
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) {
      const double cross = r == k ? 0.0 : (((k - r + 3) % 3 == 1 ? -1.0 : 1.0) * u[3 - r - k]);
      Q[r * 3 + k] = (r == k ? c : 0.0) + (1 - c) * u[r] * u[k] + s * cross;
    }
  std::vector<double> A(9, 0.0);
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k)
      for (int e = 0; e < 3; ++e) A[size_t(r) * 3 + k] += Q[r * 3 + e] * lambda[e] * Q[k * 3 + e];
  return A;
}

TEST(CovarianceStages, BlockRankCountsTheDirectionsAboveRounding) {
  std::vector<double> work;
  const double full[3] = {9.0, 1.0, 1e-6}, flat[3] = {9.0, 1.0, 1e-17}, line[3] = {4.0, 0.0, 0.0};
  EXPECT_EQ(sba::block_rank(with_eigenvalues(full).data(), 3, work), 3);
  // An eigenvalue at rounding level of the largest is no direction, whatever its sign.
  EXPECT_EQ(sba::block_rank(with_eigenvalues(flat).data(), 3, work), 2);
  EXPECT_EQ(sba::block_rank(with_eigenvalues(line).data(), 3, work), 1);
  const std::vector<double> zero(9, 0.0);
  EXPECT_EQ(sba::block_rank(zero.data(), 3, work), 0);
}

TEST(CovarianceStages, PseudoInverseInvertsTheDeterminedDirectionsOnly) {
  const double lambda[3] = {4.0, 0.5, 0.0}, inverse[3] = {0.25, 2.0, 0.0};
  std::vector<double> S = with_eigenvalues(lambda);
  const std::vector<double> want = with_eigenvalues(inverse);
  int polls = 0, rank = -1;
  const sba::Logger quiet;
  ASSERT_TRUE(sba::pseudo_inverse(S, 3, [&] { return ++polls < 0; }, quiet, &rank));
  EXPECT_EQ(rank, 2);
  EXPECT_EQ(polls, 4);  // after the decomposition, then at each of the 3 eigenvectors
  for (size_t q = 0; q < 9; ++q) EXPECT_NEAR(S[q], want[q], 1e-13) << q;
  // Abandoned at the first poll: false, and nothing said.
  std::vector<std::string> lines;
  const sba::Logger log(0, keep_line, &lines);
  S = with_eigenvalues(lambda);
  EXPECT_FALSE(sba::pseudo_inverse(S, 3, [] { return true; }, log, &rank));
  EXPECT_TRUE(lines.empty());
  // Nothing to invert: rank 0, no poll.
  std::vector<double> none;
  polls = 0;
  EXPECT_TRUE(sba::pseudo_inverse(none, 0, [&] { return ++polls < 0; }, quiet, &rank));
  EXPECT_EQ(rank, 0);
  EXPECT_EQ(polls, 0);
}

// Three cameras of two parameters, the first fixed (mcon = 1), seen by one point each.
sba::Layout three_cameras(const sba::CameraParamOptions &o) {
  sba::Layout lay;
  const char vmask[3] = {1, 1, 1};
  std::string msg;
  EXPECT_TRUE(sba::build_layout(lay, sba::Mode::MotStr, 1, 3, 1, 0, 2, 3, 2, vmask, &msg)) << msg;
  lay.cams = sba::make_camera_map(o, lay);
  return lay;
}

// S over the free parameters (cameras 1 and 2, parameters 0 and 1): entry (r, c) = 10 r + c.
std::vector<double> numbered(int n) {
  std::vector<double> S(size_t(n) * size_t(n));
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) S[size_t(r) * n + c] = 10.0 * r + c;
  return S;
}

// The covariance's unknowns are the layout's camera map's (camera_map.h): S over the free
// parameters reduced to them, and the pseudo-inverse expanded back.
TEST(CovarianceStages, WithoutHeldOrSharedParametersTheMapIsTheIdentity) {
  const sba::Layout lay = three_cameras(sba::CameraParamOptions{});
  EXPECT_TRUE(lay.cams.plain());
  EXPECT_EQ(lay.free_cams() * lay.cnp, 4);
  EXPECT_EQ(lay.cams.unknowns(), 4);
}

TEST(CovarianceStages, AHeldParameterIsNoUnknownAndHasNoCovariance) {
  const char fixed[2] = {0, 1};  // parameter 1 of every camera
  sba::CameraParamOptions o;
  o.fixed = fixed;
  const sba::Layout lay = three_cameras(o);
  const sba::CameraMap &T = lay.cams;
  ASSERT_FALSE(T.plain());
  EXPECT_EQ(T.unknowns(), 2);
  EXPECT_EQ((std::vector<int>{T.unknown(1, 0), T.unknown(1, 1), T.unknown(2, 0), T.unknown(2, 1)}),
            (std::vector<int>{0, -1, 1, -1}));
  const std::vector<double> Z = T.reduce_matrix(numbered(4));
  EXPECT_EQ(Z, (std::vector<double>{0, 2, 20, 22}));
  EXPECT_EQ(T.expand_matrix(Z), (std::vector<double>{0, 0, 2, 0, 0, 0, 0, 0, 20, 0, 22, 0, 0, 0, 0, 0}));
}

TEST(CovarianceStages, ASharedParameterIsOneUnknownWhoseRowsAreSummed) {
  const int group[6] = {-1, -1, 0, -1, 0, -1};  // parameter 0 of cameras 1 and 2
  sba::CameraParamOptions o;
  o.param_group = group;
  const sba::Layout lay = three_cameras(o);
  const sba::CameraMap &T = lay.cams;
  ASSERT_FALSE(T.plain());
  EXPECT_EQ(T.unknowns(), 3);
  // Blocks by their cameras: camera 1's own parameter 1, the shared one, camera 2's own.
  EXPECT_EQ((std::vector<int>{T.unknown(1, 0), T.unknown(1, 1), T.unknown(2, 0), T.unknown(2, 1)}),
            (std::vector<int>{1, 0, 1, 2}));
  const std::vector<double> Z = T.reduce_matrix(numbered(4));
  EXPECT_EQ(Z, (std::vector<double>{11, 10 + 12, 13, 1 + 21, 0 + 2 + 20 + 22, 3 + 23, 31, 30 + 32, 33}));
  // Back over the parameters: the shared unknown's entries in each camera's copy.
  const std::vector<double> S = T.expand_matrix(Z);
  EXPECT_EQ(S[0], 44.0);
  EXPECT_EQ(S[2], 44.0);
  EXPECT_EQ(S[1 * 4 + 3], 13.0);
  EXPECT_EQ(S[3 * 4 + 0], 62.0);
}

TEST(CovarianceStages, ResidualVarianceNeedsRedundancy) {
  sba::Layout lay = three_cameras(sba::CameraParamOptions{});  // 3 projections of 2: 6 measurements
  sba::CovarianceRequest req;
  std::vector<std::string> lines;
  const sba::Logger log(0, keep_line, &lines);
  // 2 determined camera unknowns of 4, the point's 3: dof 1.
  ASSERT_TRUE(sba::residual_variance(lay, 0.75, 4, 2, log, req));
  EXPECT_EQ(req.sigma2, 0.75);
  EXPECT_EQ(req.rank, 5);
  EXPECT_EQ(req.nfree, 7);
  EXPECT_FALSE(sba::residual_variance(lay, 0.75, 4, 3, log, req));
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0], "sba: no redundancy (measurements - rank = 0): the residual variance is undefined");
}

}  // namespace
