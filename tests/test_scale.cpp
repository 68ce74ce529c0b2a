// SPDX-License-Identifier: BSD-3-Clause
// Scale: a 20000-camera, 1,000,000-point long sequence given by its (point, camera) pairs
// (sba_motstr_levmar_x_vis). Its dense vmask alone would take 20 GB; the solve must run in
// memory proportional to the 3 million observations.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <cmath>
#include <random>
#include <vector>

#include "sba_ext.h"
#include "synth.h"

namespace {

using synth::kCnp;
using synth::kMnp;
using synth::kPnp;

long peak_rss_bytes() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss * 1024L;
}

// Offsets in 64-bit, as sba_ext.h asks of callbacks for the _vis entry points.
struct Scene {
  int n = 0, m = 0;
};
void func(double *p, sba_crsm *idx, int *, int *, double *hx, void *) {
  const size_t m = size_t(idx->nc);
  for (int i = 0; i < idx->nr; ++i)
    for (int k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k)
      synth::project(p + size_t(idx->colidx[k]) * kCnp, p + m * kCnp + size_t(i) * kPnp,
                     hx + size_t(idx->val[k]) * kMnp, nullptr, nullptr);
}
void fjac(double *p, sba_crsm *idx, int *, int *, double *jac, void *) {
  const size_t m = size_t(idx->nc), jb = kMnp * (kCnp + kPnp);
  double x[2];
  for (int i = 0; i < idx->nr; ++i)
    for (int k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k) {
      double *blk = jac + size_t(idx->val[k]) * jb;
      synth::project(p + size_t(idx->colidx[k]) * kCnp, p + m * kCnp + size_t(i) * kPnp, x, blk,
                     blk + kMnp * kCnp);
    }
}

TEST(Scale, TwentyThousandCamerasAndAMillionPointsInMemoryProportionalToObservations) {
  const int m = 20000, n = 1000000, track = 3;
  const long rss0 = peak_rss_bytes();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::normal_distribution<double> N(0.0, 1.0);
  // Cameras along the x axis, 0.1 apart, looking down +z; point i is seen by cameras
  // j0 .. j0+2 from 5 units away.
  std::vector<double> truth(size_t(m) * kCnp + size_t(n) * kPnp);
  for (int j = 0; j < m; ++j) {
    double *a = truth.data() + size_t(j) * kCnp;
    // R = I, t = -c with c = (0.1 j, 0, 0). The Euler angles rotate about the world origin,
    // 2000 units away at the end of the sequence, so their perturbation below is tiny.
    a[0] = a[1] = a[2] = 0.0;
    a[3] = -0.1 * j;
    a[4] = 0.0;
    a[5] = 0.0;
  }
  std::vector<int> vp, vc;
  vp.reserve(size_t(n) * track);
  vc.reserve(size_t(n) * track);
  for (int i = 0; i < n; ++i) {
    const int j0 = int(size_t(i) * size_t(m - track) / size_t(n));
    double *X = truth.data() + size_t(m) * kCnp + size_t(i) * kPnp;
    X[0] = 0.1 * (j0 + 1) + 0.05 * U(rng);
    X[1] = U(rng);
    X[2] = 5.0 + U(rng);
    for (int d = 0; d < track; ++d) vp.push_back(i), vc.push_back(j0 + d);
  }
  const sba_visibility vis{(long long)vp.size(), vp.data(), vc.data()};
  std::vector<double> x(vp.size() * kMnp);
  for (size_t k = 0; k < vp.size(); ++k) {
    synth::project(truth.data() + size_t(vc[k]) * kCnp, truth.data() + size_t(m) * kCnp + size_t(vp[k]) * kPnp,
                   x.data() + k * kMnp, nullptr, nullptr);
    x[k * kMnp] += 0.5 * N(rng);
    x[k * kMnp + 1] += 0.5 * N(rng);
  }
  std::vector<double> p = truth;
  const int mcon = 2;  // two fixed cameras fix the gauge
  for (int j = mcon; j < m; ++j)
    for (int c = 0; c < kCnp; ++c) p[size_t(j) * kCnp + c] += (c < 3 ? 2e-6 : 0.005) * U(rng);
  for (size_t q = size_t(m) * kCnp; q < p.size(); ++q) p[q] += 0.03 * U(rng);

  double info[SBA_INFOSZ];
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  sba_ext_result res;
  sba_ext_result_init(&res);
  ext.result = &res;
  const int ret = sba_motstr_levmar_x_vis(n, 0, m, mcon, &vis, p.data(), kCnp, kPnp, x.data(), nullptr,
                                          kMnp, func, fjac, nullptr, 20, 0, nullptr, info, &ext);
  const long used = peak_rss_bytes() - rss0;
  const double nobs = double(vp.size());
  std::printf("nvis %zu: ret %d, reason %g, error %g -> %g per projection, %g linear systems, "
              "solver %s, peak RSS growth %.0f MB (%.0f bytes per observation)\n",
              vp.size(), ret, info[6], info[0] / nobs, info[1] / nobs, info[9], res.linsolver,
              used / 1e6, used / nobs);
  ASSERT_GT(ret, 0);
  EXPECT_STREQ(res.linsolver, "sparse-chol");
  // 20 iterations take the error from the perturbed start (about 7 pixels^2 per projection)
  // to the noise floor: 2 sigma^2 (1 - unknowns / measurements) = 0.5 * (1 - 3.12M / 6M) = 0.24.
  EXPECT_GT(info[0] / nobs, 5.0);
  EXPECT_LT(info[1] / nobs, 0.26);
  // Everything the test itself holds (truth, p, x, pairs) plus the solver's workspace: far
  // below the 20 GB of a dense vmask, and bounded per observation.
  EXPECT_LT(used, 700.0 * nobs);
}

}  // namespace

namespace {

// The visible (point, camera) pairs of a problem's vmask, in sba's order.
struct Pairs {
  std::vector<int> point, camera;
  explicit Pairs(const synth::Problem &pb) {
    for (int i = 0; i < pb.n; ++i)
      for (int j = 0; j < pb.m; ++j)
        if (pb.vmask[size_t(i) * pb.m + j]) point.push_back(i), camera.push_back(j);
  }
  sba_visibility vis() const { return {(long long)point.size(), point.data(), camera.data()}; }
};

// The pairs entry points solve exactly what the vmask ones solve, given the same solver.
TEST(VisibilityPairs, SameResultAsTheVmaskEntryPoints) {
  synth::Problem pb = synth::make(60, 6, 0.5, 0.05, 61);
  const Pairs pairs(pb);
  const sba_visibility vis = pairs.vis();
  sba_ext_options ext;  // no solver named: auto, as for the pairs entry points without options
  sba_ext_options_init(&ext);
  sba_ext_result res;
  sba_ext_result_init(&res);
  ext.result = &res;
  std::vector<double> a = pb.p0, b = pb.p0, c = pb.p0;
  double ia[SBA_INFOSZ], ib[SBA_INFOSZ], ic[SBA_INFOSZ];
  const int ra = sba_motstr_levmar_x_ext(pb.n, 0, pb.m, 1, pb.vmask.data(), a.data(), kCnp, kPnp,
                                         pb.x.data(), nullptr, kMnp, synth::func_motstr,
                                         synth::fjac_motstr, &pb, 100, 0, nullptr, ia, &ext);
  const int rb = sba_motstr_levmar_x_vis(pb.n, 0, pb.m, 1, &vis, b.data(), kCnp, kPnp, pb.x.data(),
                                         nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb,
                                         100, 0, nullptr, ib, nullptr);
  const int rc = sba_motstr_levmar_vis(pb.n, 0, pb.m, 1, &vis, c.data(), kCnp, kPnp, pb.x.data(),
                                       nullptr, kMnp, synth::proj_motstr, synth::projac_motstr, &pb,
                                       100, 0, nullptr, ic, nullptr);
  ASSERT_GT(ra, 0);
  EXPECT_STREQ(res.linsolver, "chol");  // 36 camera unknowns: a dense S
  EXPECT_EQ(rb, ra);
  EXPECT_EQ(rc, ra);
  EXPECT_EQ(b, a);
  EXPECT_EQ(c, a);
  EXPECT_EQ(ib[1], ia[1]);
}

// Motion only, structure only and the covariance by pairs: the same bits as with the vmask.
TEST(VisibilityPairs, MotionOnlyStructureOnlyAndCovarianceAsTheVmaskEntryPoints) {
  synth::Problem pb = synth::make(60, 6, 0.5, 0.05, 63);
  const Pairs pairs(pb);
  const sba_visibility vis = pairs.vis();
  pb.fixed_points = pb.truth.data() + size_t(pb.m) * kCnp;
  pb.fixed_cams = pb.truth.data();
  std::vector<double> a(pb.p0.begin(), pb.p0.begin() + pb.m * kCnp), b = a;
  double ia[SBA_INFOSZ], ib[SBA_INFOSZ];
  const int ra = sba_mot_levmar_x_ext(pb.n, pb.m, 1, pb.vmask.data(), a.data(), kCnp, pb.x.data(), nullptr, kMnp,
                                      synth::func_mot, synth::fjac_mot, &pb, 50, 0, nullptr, ia, nullptr);
  const int rb = sba_mot_levmar_x_vis(pb.n, pb.m, 1, &vis, b.data(), kCnp, pb.x.data(), nullptr, kMnp,
                                      synth::func_mot, synth::fjac_mot, &pb, 50, 0, nullptr, ib, nullptr);
  ASSERT_GT(ra, 0);
  EXPECT_EQ(rb, ra);
  EXPECT_EQ(b, a);
  EXPECT_EQ(std::vector<double>(ib, ib + SBA_INFOSZ), std::vector<double>(ia, ia + SBA_INFOSZ));
  std::vector<double> s(pb.p0.begin() + pb.m * kCnp, pb.p0.end()), t = s;
  const int rs = sba_str_levmar_x_ext(pb.n, 2, pb.m, pb.vmask.data(), s.data(), kPnp, pb.x.data(), nullptr, kMnp,
                                      synth::func_str, synth::fjac_str, &pb, 50, 0, nullptr, ia, nullptr);
  const int rt = sba_str_levmar_x_vis(pb.n, 2, pb.m, &vis, t.data(), kPnp, pb.x.data(), nullptr, kMnp,
                                      synth::func_str, synth::fjac_str, &pb, 50, 0, nullptr, ib, nullptr);
  ASSERT_GT(rs, 0);
  EXPECT_EQ(rt, rs);
  EXPECT_EQ(t, s);
  EXPECT_EQ(std::vector<double>(ib, ib + SBA_INFOSZ), std::vector<double>(ia, ia + SBA_INFOSZ));

  std::vector<double> p = pb.p0;
  ASSERT_GT(sba_motstr_levmar_x(pb.n, 0, pb.m, 1, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(), nullptr, kMnp,
                                synth::func_motstr, synth::fjac_motstr, &pb, 100, 0, nullptr, nullptr),
            0);
  std::vector<int> cams(size_t(pb.m)), pts(size_t(pb.n));
  for (int j = 0; j < pb.m; ++j) cams[size_t(j)] = j;
  for (int i = 0; i < pb.n; ++i) pts[size_t(i)] = i;
  std::vector<double> cc[2], pc[2];
  sba_covariance_request req[2];
  for (int k = 0; k < 2; ++k) {
    cc[k].resize(size_t(pb.m) * kCnp * kCnp);
    pc[k].resize(size_t(pb.n) * kPnp * kPnp);
    sba_covariance_request_init(&req[k]);
    req[k].ncams = pb.m;
    req[k].cams = cams.data();
    req[k].camcov = cc[k].data();
    req[k].npts = pb.n;
    req[k].pts = pts.data();
    req[k].ptcov = pc[k].data();
  }
  EXPECT_EQ(sba_motstr_covariance_x(pb.n, 0, pb.m, 1, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(), nullptr,
                                    kMnp, synth::func_motstr, synth::fjac_motstr, &pb, &req[0], nullptr),
            0);
  EXPECT_EQ(sba_motstr_covariance_x_vis(pb.n, 0, pb.m, 1, &vis, p.data(), kCnp, kPnp, pb.x.data(), nullptr, kMnp,
                                        synth::func_motstr, synth::fjac_motstr, &pb, &req[1], nullptr),
            0);
  EXPECT_EQ(cc[1], cc[0]);
  EXPECT_EQ(pc[1], pc[0]);
  EXPECT_EQ(req[1].sigma2, req[0].sigma2);
  EXPECT_EQ(req[1].rank, req[0].rank);
}

TEST(VisibilityPairs, BadPairListsAreRefused) {
  synth::Problem pb = synth::make(10, 3, 0.5, 0.05, 62, 1.0);
  std::vector<int> vp, vc;
  for (int i = 0; i < pb.n; ++i)
    for (int j = 0; j < pb.m; ++j) vp.push_back(i), vc.push_back(j);
  std::vector<double> p = pb.p0;
  auto call = [&](const sba_visibility *vis) {
    return sba_motstr_levmar_x_vis(pb.n, 0, pb.m, 1, vis, p.data(), kCnp, kPnp, pb.x.data(), nullptr,
                                   kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 10, 0, nullptr,
                                   nullptr, nullptr);
  };
  testing::internal::CaptureStderr();
  EXPECT_EQ(call(nullptr), SBA_ERROR);
  std::vector<int> swapped = vc;
  std::swap(swapped[3], swapped[4]);
  const sba_visibility unsorted{(long long)vp.size(), vp.data(), swapped.data()};
  EXPECT_EQ(call(&unsorted), SBA_ERROR);
  std::vector<int> far = vc;
  far[5] = pb.m;
  const sba_visibility range{(long long)vp.size(), vp.data(), far.data()};
  EXPECT_EQ(call(&range), SBA_ERROR);
  const sba_visibility empty{0, vp.data(), vc.data()};
  EXPECT_EQ(call(&empty), SBA_ERROR);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("vis is NULL"), std::string::npos) << err;
  EXPECT_NE(err.find("vis pair 4 is out of order"), std::string::npos) << err;
  EXPECT_NE(err.find("vis pair 5 (point 1, camera 3) is out of range"), std::string::npos) << err;
  EXPECT_NE(err.find("between 1 and INT_MAX pairs (got 0)"), std::string::npos) << err;
  EXPECT_EQ(p, pb.p0);
}

}  // namespace
