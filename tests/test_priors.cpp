// SPDX-License-Identifier: BSD-3-Clause
// Priors (sba_ext.h: sba_camera_prior, sba_camera_linear_prior, sba_point_prior): what they do
// to a solution (a shifted scene pulled back, a parameter pinned, a shared parameter's prior
// counted per camera), the same bits for 1 and 2 threads under every solver and strategy, the
// covariance against a dense inverse of J^T J with the priors' rows, the Jacobian check of a
// callback prior, and the refusal of every kind of bad prior by name.
#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <cstring>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "cameras/euclidean.h"
#include "generator/sbagen.h"
#include "sba_ext.h"
#include "synth.h"

namespace {

using synth::kCnp;
using synth::kMnp;
using synth::kPnp;

// The camera centre C = -R^T t of a synth camera, and dC/da (3 x 6).
void centre(const double *a, double *C, double *dC) {
  const synth::Rot rot = synth::rotation(a);
  for (int r = 0; r < 3; ++r) {
    C[r] = 0.0;
    for (int q = 0; q < 3; ++q) C[r] -= rot.R[q * 3 + r] * a[3 + q];
  }
  if (!dC) return;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) {
      double s = 0.0;
      for (int q = 0; q < 3; ++q) s -= rot.dR[k][q * 3 + r] * a[3 + q];
      dC[r * kCnp + k] = s;
    }
    for (int q = 0; q < 3; ++q) dC[r * kCnp + 3 + q] = -rot.R[q * 3 + r];
  }
}

// A GPS fix of camera centres: data points to the m known centres (3 each).
void gps_func(int j, const double *aj, double *r, void *data) {
  const double *known = static_cast<const double *>(data) + 3 * j;
  centre(aj, r, nullptr);
  for (int q = 0; q < 3; ++q) r[q] -= known[q];
}
void gps_jacf(int, const double *aj, double *jac, void *) {
  double C[3];
  centre(aj, C, jac);
}
// The same with one entry wrong, for the Jacobian check.
void gps_jacf_wrong(int j, const double *aj, double *jac, void *data) {
  gps_jacf(j, aj, jac, data);
  jac[1 * kCnp + 4] += 0.5;
}

std::vector<double> true_centres(const synth::Problem &pb) {
  std::vector<double> c(size_t(pb.m) * 3);
  for (int j = 0; j < pb.m; ++j) centre(pb.truth.data() + j * kCnp, c.data() + 3 * j, nullptr);
  return c;
}

// Every line the library says, for the tests that read its messages.
struct Lines {
  std::vector<std::string> all;
  static void sink(void *ctx, int, const char *line) { static_cast<Lines *>(ctx)->all.push_back(line); }
  std::string joined() const {
    std::string s;
    for (const std::string &l : all) s += l + "\n";
    return s;
  }
};

// The priors of a call, and what it asks of the solve.
struct Call {
  std::vector<sba_camera_prior> cams;
  std::vector<sba_camera_linear_prior> linear;
  std::vector<sba_point_prior> points;
  const char *linsolver = "chol";
  const char *strategy = "sba";
  const char *loss = nullptr;
  const char *cam_fixed = nullptr;
  int nthreads = 1;
  int itmax = 100;
  int mcon = 0, ncon = 0;
  int (*progress)(void *, const sba_progress *) = nullptr;
  void *progress_ctx = nullptr;
};

struct Run {
  int ret = 0;
  std::vector<double> p;
  double info[SBA_INFOSZ] = {};
  sba_ext_result res{};
  Lines lines;
};

void fill_ext(const Call &c, sba_ext_options *ext) {
  sba_ext_options_init(ext);
  ext->linsolver = c.linsolver;
  ext->strategy = c.strategy;
  ext->nthreads = c.nthreads;
  ext->loss = c.loss;
  ext->cam_fixed = c.cam_fixed;
  ext->progress = c.progress;
  ext->progress_ctx = c.progress_ctx;
  ext->ncamera_priors = int(c.cams.size());
  ext->camera_priors = c.cams.empty() ? nullptr : c.cams.data();
  ext->ncamera_linear_priors = int(c.linear.size());
  ext->camera_linear_priors = c.linear.empty() ? nullptr : c.linear.data();
  ext->npoint_priors = int(c.points.size());
  ext->point_priors = c.points.empty() ? nullptr : c.points.data();
}

std::unique_ptr<Run> solve(synth::Problem &pb, const std::vector<double> &p0, const Call &c) {
  auto r = std::make_unique<Run>();
  r->p = p0;
  sba_ext_options ext;
  fill_ext(c, &ext);
  sba_ext_result_init(&r->res);
  ext.result = &r->res;
  ext.log = Lines::sink;
  ext.log_ctx = &r->lines;
  const double opts[SBA_OPTSSZ] = {1e-3, 1e-14, 1e-14, 1e-14, 0.0};
  r->ret = sba_motstr_levmar_x_ext(pb.n, c.ncon, pb.m, c.mcon, pb.vmask.data(), r->p.data(), kCnp, kPnp,
                                   pb.x.data(), nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb,
                                   c.itmax, 0, opts, r->info, &ext);
  return r;
}

// The scene moved by d as a whole, which leaves every projection as it was: the points by d,
// each camera's translation by -R d.
std::vector<double> shifted(const synth::Problem &pb, const std::vector<double> &p, const double d[3]) {
  std::vector<double> q = p;
  for (int j = 0; j < pb.m; ++j) {
    const synth::Rot rot = synth::rotation(q.data() + j * kCnp);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) q[size_t(j) * kCnp + 3 + r] -= rot.R[r * 3 + c] * d[c];
  }
  for (int i = 0; i < pb.n; ++i)
    for (int c = 0; c < 3; ++c) q[size_t(pb.m) * kCnp + size_t(i) * kPnp + c] += d[c];
  return q;
}

sba_point_prior point_prior(int i, const double *mean, const double *sigma) {
  sba_point_prior pr{};
  pr.point = i;
  pr.mean = mean;
  pr.weight.sigma = sigma;
  return pr;
}

sba_camera_prior gps_prior(int j, std::vector<double> &known, const double *sigma) {
  sba_camera_prior pr{};
  pr.camera = j;
  pr.dim = 3;
  pr.func = gps_func;
  pr.jacf = gps_jacf;
  pr.data = known.data();
  pr.weight.sigma = sigma;
  return pr;
}

bool same_bits(const std::vector<double> &a, const std::vector<double> &b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

const double kSigmaPoint[3] = {0.01, 0.01, 0.01};

TEST(Priors, PointPriorsPullAShiftedSceneBack) {
  synth::Problem pb = synth::make(60, 6, 0.1, 0.0, 3);
  const double d[3] = {0.4, -0.3, 0.2};
  const std::vector<double> start = shifted(pb, pb.truth, d);
  // Without priors the shifted scene fits the projections as well as the true one: it stays.
  Call none;
  const auto free = solve(pb, start, none);
  ASSERT_GT(free->ret, 0) << free->lines.joined();
  const double *truth_pts = pb.truth.data() + pb.m * kCnp;
  EXPECT_GT(std::fabs(free->p[size_t(pb.m) * kCnp] - truth_pts[0]), 0.3);
  // With a strong prior at its true place on every point, each point ends within its
  // deviation of its mean.
  Call c;
  for (int i = 0; i < pb.n; ++i) c.points.push_back(point_prior(i, truth_pts + i * kPnp, kSigmaPoint));
  const auto r = solve(pb, start, c);
  ASSERT_GT(r->ret, 0) << r->lines.joined();
  for (int i = 0; i < pb.n; ++i)
    for (int a = 0; a < kPnp; ++a)
      EXPECT_LT(std::fabs(r->p[size_t(pb.m) * kCnp + size_t(i) * kPnp + a] - truth_pts[i * kPnp + a]), kSigmaPoint[a])
          << "point " << i;
  // The result reports the cost apart; info[1] is their sum.
  EXPECT_GT(r->res.prior_cost_initial, 1e3);
  EXPECT_GT(r->res.prior_cost_final, 0.0);
  EXPECT_LT(r->res.prior_cost_final, r->res.prior_cost_initial);
  EXPECT_EQ(r->res.cost_final, r->res.projection_cost_final + r->res.prior_cost_final);
  EXPECT_EQ(r->info[1], r->res.cost_final);
  EXPECT_EQ(r->info[0], r->res.projection_cost_initial + r->res.prior_cost_initial);
  EXPECT_EQ(r->res.sq_error_final, r->res.projection_cost_final);  // no loss
}

TEST(Priors, ACallbackPriorOnTheCameraCentresPlacesTheScene) {
  synth::Problem pb = synth::make(60, 6, 0.1, 0.0, 5);
  const double d[3] = {0.0, 0.5, -0.5};
  const std::vector<double> start = shifted(pb, pb.truth, d);
  std::vector<double> known = true_centres(pb);
  const double sigma[3] = {1e-3, 1e-3, 1e-3};
  Call c;
  for (int j = 0; j < pb.m; ++j) c.cams.push_back(gps_prior(j, known, sigma));
  const auto r = solve(pb, start, c);
  ASSERT_GT(r->ret, 0) << r->lines.joined();
  for (int j = 0; j < pb.m; ++j) {
    double C[3];
    centre(r->p.data() + j * kCnp, C, nullptr);
    for (int q = 0; q < 3; ++q) EXPECT_LT(std::fabs(C[q] - known[size_t(j) * 3 + q]), 3 * sigma[q]) << j;
  }
  // Differences instead of jacf: the same minimum.
  for (sba_camera_prior &pr : c.cams) pr.jacf = nullptr;
  const auto fd = solve(pb, start, c);
  ASSERT_GT(fd->ret, 0);
  for (size_t q = 0; q < r->p.size(); ++q) EXPECT_NEAR(fd->p[q], r->p[q], 1e-6);
}

TEST(Priors, ALinearPriorPinsACameraParameter) {
  synth::Problem pb = synth::make(60, 6, 0.3, 0.05, 7);
  const double mean = pb.truth[2 * kCnp + 5] + 0.2, sigma = 1e-4;
  const int param = 5;
  Call c;
  sba_camera_linear_prior pr{};
  pr.camera = 2;
  pr.k = 1;
  pr.params = &param;
  pr.mean = &mean;
  pr.weight.sigma = &sigma;
  c.linear.push_back(pr);
  const auto r = solve(pb, pb.p0, c);
  ASSERT_GT(r->ret, 0) << r->lines.joined();
  EXPECT_LT(std::fabs(r->p[2 * kCnp + 5] - mean), 3 * sigma);
  const auto none = solve(pb, pb.p0, Call{});
  EXPECT_GT(std::fabs(none->p[2 * kCnp + 5] - mean), 0.1);
}

// A scene with priors of every kind, a loss on the projections and one on a prior.
struct Mixed {
  synth::Problem pb = synth::make(60, 6, 0.5, 0.05, 11);
  std::vector<double> known = true_centres(pb);
  double sigma_c[3] = {0.05, 0.05, 0.05};
  double mean_l = 0.0, sigma_l = 0.01;
  int param_l = 3;
  Call call;
  Mixed() {
    mean_l = pb.truth[1 * kCnp + 3];
    const double *pts = pb.truth.data() + pb.m * kCnp;
    for (int i = 0; i < 5; ++i) call.points.push_back(point_prior(3 * i, pts + 3 * i * kPnp, kSigmaPoint));
    call.points.back().loss = "cauchy";
    call.points.back().loss_scale = 0.5;
    call.cams.push_back(gps_prior(0, known, sigma_c));
    call.cams.push_back(gps_prior(4, known, sigma_c));
    sba_camera_linear_prior pr{};
    pr.camera = 1;
    pr.k = 1;
    pr.params = &param_l;
    pr.mean = &mean_l;
    pr.weight.sigma = &sigma_l;
    call.linear.push_back(pr);
    call.loss = "huber";
  }
};

std::vector<std::string> names(const char *list) {
  std::vector<std::string> out;
  std::istringstream in(list);
  for (std::string s; in >> s;) out.push_back(s);
  return out;
}

TEST(Priors, EverySolverAndStrategyGivesTheSameBitsForOneAndTwoThreads) {
  Mixed s;
  const auto ref = solve(s.pb, s.pb.p0, s.call);
  ASSERT_GT(ref->ret, 0) << ref->lines.joined();
  for (const std::string &solver : names(sba_linsolver_names()))
    for (const std::string &strategy : names(sba_strategy_names())) {
      Call c = s.call;
      c.linsolver = solver.c_str();
      c.strategy = strategy.c_str();
      c.nthreads = 1;
      const auto one = solve(s.pb, s.pb.p0, c);
      c.nthreads = 2;
      const auto two = solve(s.pb, s.pb.p0, c);
      const std::string what = solver + " " + strategy;
      ASSERT_GT(one->ret, 0) << what << "\n" << one->lines.joined();
      EXPECT_EQ(two->res.nthreads, 2) << what;
      EXPECT_EQ(one->ret, two->ret) << what;
      EXPECT_TRUE(same_bits(one->p, two->p)) << what;
      EXPECT_EQ(0, std::memcmp(one->info, two->info, sizeof one->info)) << what;
      EXPECT_NEAR(one->info[1], ref->info[1], 1e-4 * ref->info[1]) << what;
      EXPECT_GT(one->res.prior_cost_final, 0.0) << what;
    }
}

// The covariance of the solution with priors against sigma^2 (J^T J)^-1 formed densely: the
// projections' rows and the priors' (weighted) rows, over every parameter. The priors fix the
// gauge: three points and two camera centres.
struct DenseSystem {
  int nfree = 0, rows = 0;
  std::vector<double> J, e;  // rows x nfree, rows
  void add_row(const std::vector<double> &row, double residual) {
    J.insert(J.end(), row.begin(), row.end());
    e.push_back(residual);
    ++rows;
  }
};

void projection_rows(synth::Problem &pb, const std::vector<double> &p, DenseSystem &D) {
  const int off_pts = pb.m * kCnp;
  int k = 0;
  for (int i = 0; i < pb.n; ++i)
    for (int j = 0; j < pb.m; ++j) {
      if (!pb.vmask[size_t(i) * pb.m + j]) continue;
      double x[2], A[kMnp * kCnp], B[kMnp * kPnp];
      synth::project(p.data() + j * kCnp, p.data() + off_pts + i * kPnp, x, A, B);
      for (int r = 0; r < kMnp; ++r) {
        std::vector<double> row(size_t(D.nfree), 0.0);
        for (int a = 0; a < kCnp; ++a) row[size_t(j) * kCnp + a] = A[r * kCnp + a];
        for (int a = 0; a < kPnp; ++a) row[size_t(off_pts + i * kPnp + a)] = B[r * kPnp + a];
        D.add_row(row, pb.x[size_t(2 * k + r)] - x[r]);
      }
      ++k;
    }
}

void prior_rows(const Mixed &s, const std::vector<double> &p, DenseSystem &D) {
  const synth::Problem &pb = s.pb;
  for (const sba_point_prior &pr : s.call.points)
    for (int a = 0; a < kPnp; ++a) {
      std::vector<double> row(size_t(D.nfree), 0.0);
      const size_t col = size_t(pb.m) * kCnp + size_t(pr.point) * kPnp + size_t(a);
      row[col] = 1.0 / pr.weight.sigma[a];
      D.add_row(row, -(p[col] - pr.mean[a]) / pr.weight.sigma[a]);
    }
  for (const sba_camera_prior &pr : s.call.cams) {
    double r[3], dC[3 * kCnp];
    gps_func(pr.camera, p.data() + pr.camera * kCnp, r, pr.data);
    gps_jacf(pr.camera, p.data() + pr.camera * kCnp, dC, pr.data);
    for (int q = 0; q < 3; ++q) {
      std::vector<double> row(size_t(D.nfree), 0.0);
      for (int a = 0; a < kCnp; ++a) row[size_t(pr.camera) * kCnp + a] = dC[q * kCnp + a] / pr.weight.sigma[q];
      D.add_row(row, -r[q] / pr.weight.sigma[q]);
    }
  }
  for (const sba_camera_linear_prior &pr : s.call.linear) {
    std::vector<double> row(size_t(D.nfree), 0.0);
    const size_t col = size_t(pr.camera) * kCnp + size_t(pr.params[0]);
    row[col] = 1.0 / pr.weight.sigma[0];
    D.add_row(row, -(p[col] - pr.mean[0]) / pr.weight.sigma[0]);
  }
}

// (J^T J)^-1, full.
std::vector<double> dense_inverse(const DenseSystem &D) {
  const int nf = D.nfree;
  std::vector<double> JtJ(size_t(nf) * nf, 0.0);
  for (int r = 0; r < D.rows; ++r)
    for (int a = 0; a < nf; ++a) {
      const double v = D.J[size_t(r) * nf + a];
      if (v == 0.0) continue;
      for (int b = 0; b < nf; ++b) JtJ[size_t(a) * nf + b] += v * D.J[size_t(r) * nf + b];
    }
  EXPECT_EQ(sba_symat_invert_Chol(JtJ.data(), nf), 1);
  for (int a = 0; a < nf; ++a)
    for (int b = a + 1; b < nf; ++b) JtJ[size_t(a) * nf + b] = JtJ[size_t(b) * nf + a];
  return JtJ;
}

TEST(Priors, CovarianceMatchesADenseInverseWithThePriorsRows) {
  Mixed s;
  s.call.loss = nullptr;  // the dense reference has no reweighting
  for (sba_point_prior &pr : s.call.points) pr.loss = nullptr;
  const auto solved = solve(s.pb, s.pb.p0, s.call);
  ASSERT_GT(solved->ret, 0);
  std::vector<double> p = solved->p;
  DenseSystem D;
  D.nfree = s.pb.m * kCnp + s.pb.n * kPnp;
  projection_rows(s.pb, p, D);
  prior_rows(s, p, D);
  const std::vector<double> inv = dense_inverse(D);
  double e2 = 0.0;
  for (double v : D.e) e2 += v * v;
  const double sigma2 = e2 / (D.rows - D.nfree);

  std::vector<int> cams, pts;
  for (int j = 0; j < s.pb.m; ++j) cams.push_back(j);
  for (int i = 0; i < s.pb.n; ++i) pts.push_back(i);
  std::vector<double> camcov(cams.size() * kCnp * kCnp), ptcov(pts.size() * kPnp * kPnp);
  sba_covariance_request req;
  sba_covariance_request_init(&req);
  req.ncams = s.pb.m;
  req.cams = cams.data();
  req.camcov = camcov.data();
  req.npts = s.pb.n;
  req.pts = pts.data();
  req.ptcov = ptcov.data();
  sba_ext_options ext;
  fill_ext(s.call, &ext);
  ext.quiet = 1;
  ASSERT_EQ(0, sba_motstr_covariance_x(s.pb.n, 0, s.pb.m, 0, s.pb.vmask.data(), p.data(), kCnp, kPnp,
                                       s.pb.x.data(), nullptr, kMnp, synth::func_motstr, synth::fjac_motstr,
                                       &s.pb, &req, &ext));
  EXPECT_EQ(req.rank, D.nfree);  // the priors fix the gauge
  EXPECT_NEAR(req.sigma2, sigma2, 1e-10 * sigma2);
  const auto check = [&](const double *got, int base, int size) {
    double worst = 0.0;
    for (int a = 0; a < size; ++a)
      for (int b = 0; b < size; ++b) {
        const size_t ra = size_t(base + a), rb = size_t(base + b);
        const double want = req.sigma2 * inv[ra * size_t(D.nfree) + rb];
        const double scale = req.sigma2 * std::sqrt(inv[ra * size_t(D.nfree) + ra] * inv[rb * size_t(D.nfree) + rb]);
        worst = std::max(worst, std::fabs(got[a * size + b] - want) / scale);
      }
    return worst;
  };
  double worst = 0.0;
  for (int j = 0; j < s.pb.m; ++j) worst = std::max(worst, check(camcov.data() + j * kCnp * kCnp, j * kCnp, kCnp));
  for (int i = 0; i < s.pb.n; ++i)
    worst = std::max(worst, check(ptcov.data() + i * kPnp * kPnp, s.pb.m * kCnp + i * kPnp, kPnp));
  EXPECT_LT(worst, 1e-8);
}

// Point q's projections but the one on its first camera removed (x with them).
void see_once(synth::Problem &pb, int q) {
  std::vector<double> x;
  int k = 0;
  bool first = true;
  for (int i = 0; i < pb.n; ++i)
    for (int j = 0; j < pb.m; ++j) {
      if (!pb.vmask[size_t(i) * pb.m + j]) continue;
      const bool keep = i != q || first;
      if (i == q) first = false;
      if (keep) x.insert(x.end(), pb.x.begin() + 2 * k, pb.x.begin() + 2 * k + 2);
      else pb.vmask[size_t(i) * pb.m + j] = 0;
      ++k;
    }
  pb.x = x;
}

TEST(Priors, APointSeenOnceHasACovarianceWithItsPrior) {
  Mixed s;
  s.call.loss = nullptr;
  see_once(s.pb, 1);
  const auto solved = solve(s.pb, s.pb.p0, s.call);
  ASSERT_GT(solved->ret, 0);
  std::vector<double> p = solved->p;
  const int pt = 1;
  double ptcov[kPnp * kPnp];
  sba_covariance_request req;
  sba_covariance_request_init(&req);
  req.npts = 1;
  req.pts = &pt;
  req.ptcov = ptcov;
  sba_ext_options ext;
  fill_ext(s.call, &ext);
  Lines lines;
  ext.log = Lines::sink;
  ext.log_ctx = &lines;
  const auto covariance = [&] {
    return sba_motstr_covariance_x(s.pb.n, 0, s.pb.m, 0, s.pb.vmask.data(), p.data(), kCnp, kPnp, s.pb.x.data(),
                                   nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &s.pb, &req, &ext);
  };
  // Its one projection leaves it undetermined...
  ASSERT_EQ(SBA_ERROR, covariance());
  EXPECT_NE(lines.joined().find("point 1 is seen by one camera only"), std::string::npos) << lines.joined();
  // ... its prior determines it.
  const double mean[3] = {p[size_t(s.pb.m) * kCnp + 3], p[size_t(s.pb.m) * kCnp + 4], p[size_t(s.pb.m) * kCnp + 5]};
  std::vector<sba_point_prior> points = s.call.points;
  points.push_back(point_prior(1, mean, kSigmaPoint));
  ext.npoint_priors = int(points.size());
  ext.point_priors = points.data();
  ASSERT_EQ(0, covariance()) << lines.joined();
  for (int a = 0; a < kPnp; ++a) EXPECT_TRUE(ptcov[a * kPnp + a] > 0.0 && std::isfinite(ptcov[a * kPnp + a]));
}

TEST(Priors, TheJacobianCheckFindsAWrongPriorJacobian) {
  Mixed s;
  s.call.itmax = 0;
  const auto good = solve(s.pb, s.pb.p0, s.call);
  EXPECT_NE(good->lines.joined().find("sba: Jacobian check: all 6 gradients of the camera priors agree with finite "
                                      "differences"),
            std::string::npos)
      << good->lines.joined();
  s.call.cams[1].jacf = gps_jacf_wrong;
  const auto bad = solve(s.pb, s.pb.p0, s.call);
  const std::string said = bad->lines.joined();
  EXPECT_NE(said.find("camera prior 1 (camera 4): gradient of residual entry 1 is probably wrong: d/d(parameter 4)"),
            std::string::npos)
      << said;
  EXPECT_NE(said.find("sba: Jacobian check: 1 of 6 gradients of the camera priors look wrong"), std::string::npos)
      << said;
}

TEST(Priors, HeldAndSharedParameters) {
  // A callback prior on a camera with held parameters: they keep their bits.
  Mixed s;
  std::vector<char> fixed(size_t(s.pb.m) * kCnp, 0);
  fixed[0 * kCnp + 0] = fixed[0 * kCnp + 1] = 1;
  s.call.cam_fixed = nullptr;
  sba_ext_options ext;
  fill_ext(s.call, &ext);
  ext.cam_fixed = fixed.data();
  ext.cam_fixed_per_camera = 1;
  ext.quiet = 1;
  std::vector<double> p = s.pb.p0;
  double info[SBA_INFOSZ];
  const double opts[SBA_OPTSSZ] = {1e-3, 1e-14, 1e-14, 1e-14, 0.0};
  ASSERT_GT(sba_motstr_levmar_x_ext(s.pb.n, 0, s.pb.m, 0, s.pb.vmask.data(), p.data(), kCnp, kPnp, s.pb.x.data(),
                                    nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &s.pb, 100, 0, opts, info,
                                    &ext),
            0);
  EXPECT_EQ(0, std::memcmp(p.data(), s.pb.p0.data(), 2 * sizeof(double)));
}

// What a solve of the Lens scene below asks beside its linear priors.
struct LensAsked {
  const char *linsolver = "chol", *strategy = "sba";
  int nthreads = 1;
  std::vector<sba_point_prior> points;
};

struct Lens {
  sbagen::Scene scene;
  std::unique_ptr<sbacameras::euclidean::CameraModel> model;
  std::vector<double> p0;
  int m = 0, n = 0;
  static constexpr int kCnp11 = 11;
  Lens() {
    using sbacameras::euclidean::CameraKind;
    sbagen::Options o;
    o.cameras = 8;
    o.points = 150;
    o.kind = CameraKind::VaryingIntrinsics;
    o.intrinsics_spread = 0.0;
    o.perturb_intrinsics = 0.0;
    o.track_min = 3;
    o.track_max = 6;
    o.focal = 800.0;
    o.noise = 0.5;
    o.seed = 9;
    std::string error;
    EXPECT_TRUE(sbagen::generate(o, &scene, &error)) << error;
    model = std::make_unique<sbacameras::euclidean::CameraModel>(CameraKind::VaryingIntrinsics, scene.initial_cameras,
                                                                 scene.initial_points(), 0, 0);
    m = model->ncameras();
    n = model->npoints();
    p0 = model->initial_camera_params();
    p0.insert(p0.end(), model->initial_points().begin(), model->initial_points().end());
  }
  using Asked = LensAsked;
  // With the lens shared by every camera and u0 v0 ar s held.
  std::vector<double> solve(const std::vector<sba_camera_linear_prior> &priors, const Asked &asked = Asked{}) {
    using sbacameras::euclidean::CameraKind;
    using sbacameras::euclidean::Refinement;
    std::vector<double> p = p0;
    const std::vector<char> fixed{0, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0}, shared{1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0};
    const std::vector<int> group(size_t(m), 0);
    sba_ext_options ext;
    sba_ext_options_init(&ext);
    ext.quiet = 1;
    ext.cam_fixed = fixed.data();
    ext.cam_group = group.data();
    ext.cam_shared = shared.data();
    ext.ncamera_linear_priors = int(priors.size());
    ext.camera_linear_priors = priors.data();
    ext.npoint_priors = int(asked.points.size());
    ext.point_priors = asked.points.data();
    ext.linsolver = asked.linsolver;
    ext.strategy = asked.strategy;
    ext.nthreads = asked.nthreads;
    sba_ext_result res;
    sba_ext_result_init(&res);
    ext.result = &res;
    const double opts[SBA_OPTSSZ] = {1e-3, 1e-14, 1e-14, 1e-14, 0.0};
    std::vector<char> vmask = sbagen::dense_vmask(scene);
    std::vector<double> x = scene.measurements.x;
    const auto cb = sbacameras::euclidean::expert_callbacks(CameraKind::VaryingIntrinsics, Refinement::MotionStructure);
    double info[SBA_INFOSZ];
    const int ret = sba_motstr_levmar_x_ext(n, 0, m, 0, vmask.data(), p.data(), kCnp11, 3, x.data(), nullptr, 2,
                                            cb.func, cb.fjac, sbacameras::euclidean::as_adata(*model), 100, 0, opts,
                                            info, &ext);
    EXPECT_GT(ret, 0) << asked.linsolver << " " << asked.strategy;
    EXPECT_EQ(res.nthreads, asked.nthreads);
    return p;
  }
};

TEST(Priors, SharedAndHeldParametersUnderEverySolverAndStrategyGiveTheSameBitsForOneAndTwoThreads) {
  Lens lens;
  const int fu = 0;
  const double mean = 790.0, sigma = 2.0;
  sba_camera_linear_prior pr{};
  pr.camera = 2;
  pr.k = 1;
  pr.params = &fu;
  pr.mean = &mean;
  pr.weight.sigma = &sigma;
  Lens::Asked asked;
  const double *pts = lens.p0.data() + size_t(lens.m) * Lens::kCnp11;
  const double sigma_pt[3] = {0.05, 0.05, 0.05};
  for (int i = 0; i < 4; ++i) asked.points.push_back(point_prior(10 * i, pts + 30 * i, sigma_pt));
  const std::vector<double> ref = lens.solve({pr}, asked);
  for (const std::string &solver : names(sba_linsolver_names()))
    for (const std::string &strategy : names(sba_strategy_names())) {
      asked.linsolver = solver.c_str();
      asked.strategy = strategy.c_str();
      asked.nthreads = 1;
      const std::vector<double> one = lens.solve({pr}, asked);
      asked.nthreads = 2;
      const std::vector<double> two = lens.solve({pr}, asked);
      EXPECT_TRUE(same_bits(one, two)) << solver << " " << strategy;
      EXPECT_NEAR(one[0], ref[0], 1e-3) << solver << " " << strategy;
      for (int j = 1; j < lens.m; ++j) EXPECT_EQ(one[size_t(j) * Lens::kCnp11], one[0]) << solver << " " << strategy;
    }
}

// The shared lens of a VaryingIntrinsics scene: a prior on the shared focal length of two
// cameras counts twice, as one prior of half the variance does.
TEST(Priors, APriorOnASharedParameterAppliesOncePerCameraThatNamesIt) {
  Lens lens;
  const int fu = 0;
  const double mean = 790.0, sigma = 2.0, half = sigma / std::sqrt(2.0);
  sba_camera_linear_prior pr{};
  pr.k = 1;
  pr.params = &fu;
  pr.mean = &mean;
  pr.weight.sigma = &sigma;
  sba_camera_linear_prior a = pr, b = pr;
  a.camera = 0;
  b.camera = 5;
  const std::vector<double> two = lens.solve({a, b});
  sba_camera_linear_prior one = pr;
  one.camera = 3;
  one.weight.sigma = &half;
  const std::vector<double> halved = lens.solve({one});
  const std::vector<double> none = lens.solve({});
  EXPECT_NEAR(two[0], halved[0], 1e-6);
  EXPECT_GT(std::fabs(two[0] - none[0]), 1e-3);
  for (int j = 1; j < lens.m; ++j) EXPECT_EQ(two[size_t(j) * Lens::kCnp11], two[0]);
}

// A bad prior is refused before anything runs, with a message naming it.
struct Bad {
  synth::Problem pb = synth::make(20, 4, 0.1, 0.05, 13);
  std::vector<double> known = true_centres(pb);
  double mean[3] = {0.1, 0.2, 0.3}, sigma[3] = {0.1, 0.1, 0.1};
  double cov[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  int param = 2;
  std::string refused(const Call &c) {
    const auto r = solve(pb, pb.p0, c);
    EXPECT_EQ(r->ret, SBA_ERROR);
    EXPECT_EQ(r->info[6], SBA_STOP_NONE);
    return r->lines.all.empty() ? std::string() : r->lines.all.back();
  }
  Call with_point(const sba_point_prior &pr) {
    Call c;
    c.points.push_back(point_prior(1, mean, sigma));
    c.points.push_back(pr);
    return c;
  }
  sba_camera_linear_prior linear(int j) const {
    sba_camera_linear_prior pr{};
    pr.camera = j;
    pr.k = 1;
    pr.params = &param;
    pr.mean = mean;
    return pr;
  }
};

const char kWho[] = "sba_motstr_levmar_x: ";

TEST(Priors, BadPointPriorsAreRefusedByName) {
  Bad b;
  double nan_mean[3] = {0.0, NAN, 0.0}, inf_mean[3] = {INFINITY, 0.0, 0.0}, neg[3] = {0.1, 0.1, -0.2};
  sba_point_prior pr = point_prior(5, nan_mean, b.sigma);
  EXPECT_EQ(b.refused(b.with_point(pr)), std::string(kWho) + "point prior 1 (point 5): mean[1] is not finite");
  pr.mean = inf_mean;
  EXPECT_EQ(b.refused(b.with_point(pr)), std::string(kWho) + "point prior 1 (point 5): mean[0] is not finite");
  pr = point_prior(5, b.mean, neg);
  EXPECT_EQ(b.refused(b.with_point(pr)),
            std::string(kWho) + "point prior 1 (point 5): weight.sigma[2] (a standard deviation) must be finite and "
                                "positive (got -0.2)");
  pr = point_prior(20, b.mean, b.sigma);
  EXPECT_EQ(b.refused(b.with_point(pr)), std::string(kWho) + "point prior 1 (point 20): there is no such point (n = 20)");
  pr = point_prior(-1, b.mean, b.sigma);
  EXPECT_EQ(b.refused(b.with_point(pr)), std::string(kWho) + "point prior 1 (point -1): there is no such point (n = 20)");
  pr = point_prior(5, nullptr, b.sigma);
  EXPECT_EQ(b.refused(b.with_point(pr)), std::string(kWho) + "point prior 1 (point 5): mean is NULL");
  Call c = b.with_point(point_prior(0, b.mean, b.sigma));
  c.ncon = 1;
  EXPECT_EQ(b.refused(c), std::string(kWho) + "point prior 1 (point 0): the point is fixed (below ncon = 1)");
}

TEST(Priors, BadWeightsAndLossesAreRefusedByName) {
  Bad b;
  const std::string who = std::string(kWho) + "point prior 1 (point 5): ";
  sba_point_prior pr = point_prior(5, b.mean, nullptr);
  double cov[9] = {1, 0.5, 0, 0.5, 1, 0, 0, 0, -1};
  pr.weight.covariance = cov;
  EXPECT_EQ(b.refused(b.with_point(pr)), who + "weight.covariance is not positive definite");
  cov[8] = 1;
  cov[1] = 0.4;
  EXPECT_EQ(b.refused(b.with_point(pr)), who + "weight.covariance is not symmetric (entries (0, 1))");
  cov[1] = NAN;
  EXPECT_EQ(b.refused(b.with_point(pr)), who + "weight.covariance[1] is not finite");
  pr.weight.covariance = nullptr;
  double L[9] = {1, 0, 0, 0, 1, 0, 0.5, 0, 1};
  pr.weight.sqrt_info = L;
  EXPECT_EQ(b.refused(b.with_point(pr)), who + "weight.sqrt_info must be upper triangular (entry (2, 0) is 0.5)");
  L[6] = 0.0;
  L[4] = 0.0;
  EXPECT_EQ(b.refused(b.with_point(pr)), who + "weight.sqrt_info's diagonal must be positive (entry (1, 1) is 0)");
  pr.weight.sigma = b.sigma;
  EXPECT_EQ(b.refused(b.with_point(pr)),
            who + "give at most one of weight.sigma, weight.covariance and weight.sqrt_info");
  pr = point_prior(5, b.mean, b.sigma);
  pr.loss = "hubber";
  EXPECT_EQ(b.refused(b.with_point(pr)),
            who + "unknown loss \"hubber\" (known: none huber cauchy soft-l1 tukey)");
  pr.loss = "huber";
  pr.loss_scale = -1.0;
  EXPECT_EQ(b.refused(b.with_point(pr)),
            who + "loss_scale must be positive and within [1.49e-154, 6.7e+153] (got -1)");
}

TEST(Priors, BadCameraPriorsAreRefusedByName) {
  Bad b;
  Call c;
  c.cams.push_back(gps_prior(4, b.known, b.sigma));
  EXPECT_EQ(b.refused(c), std::string(kWho) + "camera prior 0 (camera 4): there is no such camera (m = 4)");
  c.cams[0] = gps_prior(0, b.known, b.sigma);
  c.mcon = 1;
  EXPECT_EQ(b.refused(c), std::string(kWho) + "camera prior 0 (camera 0): the camera is fixed (below mcon = 1)");
  c.mcon = 0;
  c.cams[0].dim = 0;
  EXPECT_EQ(b.refused(c), std::string(kWho) + "camera prior 0 (camera 0): dim must be in 1..64 (got 0)");
  c.cams[0] = gps_prior(1, b.known, b.sigma);
  c.cams[0].func = nullptr;
  EXPECT_EQ(b.refused(c), std::string(kWho) + "camera prior 0 (camera 1): func is NULL");
  const std::vector<char> all(kCnp, 1);
  c.cams[0] = gps_prior(1, b.known, b.sigma);
  c.cam_fixed = all.data();
  EXPECT_EQ(b.refused(c), std::string(kWho) + "camera prior 0 (camera 1): every parameter of the camera is held "
                                              "(cam_fixed): the prior would change nothing");
}

TEST(Priors, BadLinearPriorsAreRefusedByName) {
  Bad b;
  const std::vector<char> held{0, 0, 1, 0, 0, 0};
  Call c;
  c.linear.push_back(b.linear(2));
  c.cam_fixed = held.data();
  EXPECT_EQ(b.refused(c), std::string(kWho) + "camera linear prior 0 (camera 2): params[0] = 2 is held (cam_fixed): "
                                              "a prior on a held parameter would change nothing");
  c.cam_fixed = nullptr;
  double inf_mean = INFINITY;
  c.linear[0].mean = &inf_mean;
  EXPECT_EQ(b.refused(c), std::string(kWho) + "camera linear prior 0 (camera 2): mean[0] is not finite");
  c.linear[0] = b.linear(2);
  const int twice[2] = {1, 1};
  c.linear[0].k = 2;
  c.linear[0].params = twice;
  EXPECT_EQ(b.refused(c), std::string(kWho) + "camera linear prior 0 (camera 2): params[1] = 1 is named twice");
  const int out[1] = {6};
  c.linear[0] = b.linear(2);
  c.linear[0].params = out;
  EXPECT_EQ(b.refused(c),
            std::string(kWho) + "camera linear prior 0 (camera 2): params[0] = 6 is not a camera parameter (cnp = 6)");
  c.linear[0] = b.linear(2);
  c.linear[0].k = 7;
  EXPECT_EQ(b.refused(c), std::string(kWho) + "camera linear prior 0 (camera 2): k must be in 1..cnp = 1..6 (got 7)");
}

TEST(Priors, BadCountsAndArraysAreRefused) {
  Bad b;
  Call c;
  sba_ext_options ext;
  fill_ext(c, &ext);
  Lines lines;
  ext.log = Lines::sink;
  ext.log_ctx = &lines;
  ext.npoint_priors = 2;
  std::vector<double> p = b.pb.p0;
  double info[SBA_INFOSZ];
  EXPECT_EQ(SBA_ERROR, sba_motstr_levmar_x_ext(b.pb.n, 0, b.pb.m, 0, b.pb.vmask.data(), p.data(), kCnp, kPnp,
                                               b.pb.x.data(), nullptr, kMnp, synth::func_motstr, synth::fjac_motstr,
                                               &b.pb, 10, 0, nullptr, info, &ext));
  ASSERT_FALSE(lines.all.empty());
  EXPECT_EQ(lines.all.back(), std::string(kWho) + "point_priors is NULL but npoint_priors is 2");
  ext.npoint_priors = 0;
  ext.ncamera_priors = -1;
  EXPECT_EQ(SBA_ERROR, sba_motstr_levmar_x_ext(b.pb.n, 0, b.pb.m, 0, b.pb.vmask.data(), p.data(), kCnp, kPnp,
                                               b.pb.x.data(), nullptr, kMnp, synth::func_motstr, synth::fjac_motstr,
                                               &b.pb, 10, 0, nullptr, info, &ext));
  EXPECT_EQ(lines.all.back(), std::string(kWho) + "ncamera_priors must be >= 0 (got -1)");
}

void nan_func(int, const double *, double *r, void *) { r[0] = NAN; }

TEST(Priors, ACallbackResidualThatIsNotFiniteEndsTheSolveByName) {
  Bad b;
  Call c;
  sba_camera_prior pr{};
  pr.camera = 2;
  pr.dim = 1;
  pr.func = nan_func;
  c.cams.push_back(pr);
  const auto r = solve(b.pb, b.pb.p0, c);
  EXPECT_EQ(r->ret, SBA_ERROR);
  EXPECT_EQ(r->info[6], SBA_STOP_NONFINITE);
  ASSERT_FALSE(r->lines.all.empty());
  EXPECT_EQ(r->lines.all.back(), "sba: the residual of camera prior 0 is not finite at the initial estimate");
}

TEST(Priors, ACallerOfAnOlderStructIsNotReadPastItsSize) {
  Mixed s;
  s.call.loss = nullptr;
  const auto none = solve(s.pb, s.pb.p0, Call{});
  sba_ext_options ext;
  fill_ext(s.call, &ext);  // priors set, but beyond the size the caller claims
  ext.size = offsetof(sba_ext_options, ncamera_priors);
  ext.quiet = 1;
  std::vector<double> p = s.pb.p0;
  double info[SBA_INFOSZ];
  const double opts[SBA_OPTSSZ] = {1e-3, 1e-14, 1e-14, 1e-14, 0.0};
  ASSERT_GT(sba_motstr_levmar_x_ext(s.pb.n, 0, s.pb.m, 0, s.pb.vmask.data(), p.data(), kCnp, kPnp, s.pb.x.data(),
                                    nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &s.pb, 100, 0, opts, info,
                                    &ext),
            0);
  EXPECT_TRUE(same_bits(p, none->p));
}

TEST(Priors, ThePriorsCostReachesTheProgressCallback) {
  Mixed s;
  std::vector<double> errors;
  s.call.progress = [](void *ctx, const sba_progress *st) {
    static_cast<std::vector<double> *>(ctx)->push_back(st->error);
    return 0;
  };
  s.call.progress_ctx = &errors;
  const auto r = solve(s.pb, s.pb.p0, s.call);
  ASSERT_GT(r->ret, 0);
  ASSERT_FALSE(errors.empty());
  EXPECT_EQ(errors.back(), r->info[1]);
  EXPECT_EQ(r->info[1], r->res.projection_cost_final + r->res.prior_cost_final);
}

TEST(Priors, MotionOnlyAndStructureOnlyDrivers) {
  synth::Problem pb = synth::make(40, 5, 0.1, 0.05, 17);
  std::vector<double> known = true_centres(pb);
  const double sigma[3] = {1e-4, 1e-4, 1e-4};
  // Motion only, with a camera centre prior of its own: camera 2 ends on it.
  pb.fixed_points = pb.truth.data() + pb.m * kCnp;
  std::vector<double> offset = known;
  offset[6] += 0.01;
  sba_camera_prior cp = gps_prior(2, offset, sigma);
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.quiet = 1;
  ext.ncamera_priors = 1;
  ext.camera_priors = &cp;
  std::vector<double> a(pb.p0.begin(), pb.p0.begin() + pb.m * kCnp);
  double info[SBA_INFOSZ];
  ASSERT_GT(sba_mot_levmar_x_ext(pb.n, pb.m, 0, pb.vmask.data(), a.data(), kCnp, pb.x.data(), nullptr, kMnp,
                                 synth::func_mot, synth::fjac_mot, &pb, 100, 0, nullptr, info, &ext),
            0);
  double C[3];
  centre(a.data() + 2 * kCnp, C, nullptr);
  EXPECT_LT(std::fabs(C[0] - offset[6]), 3e-4);
  // A point prior in a motion-only driver has no point to act on.
  const double mean[3] = {0, 0, 0};
  sba_point_prior pp = point_prior(0, mean, sigma);
  ext.npoint_priors = 1;
  ext.point_priors = &pp;
  Lines lines;
  ext.quiet = 0;
  ext.log = Lines::sink;
  ext.log_ctx = &lines;
  EXPECT_EQ(SBA_ERROR, sba_mot_levmar_x_ext(pb.n, pb.m, 0, pb.vmask.data(), a.data(), kCnp, pb.x.data(), nullptr,
                                            kMnp, synth::func_mot, synth::fjac_mot, &pb, 100, 0, nullptr, info, &ext));
  EXPECT_EQ(lines.all.back(), "sba_mot_levmar_x: point prior 0 (point 0): the driver has no points (motion only)");
  // Structure only, with the simple callbacks: a point ends on its prior.
  pb.fixed_cams = pb.truth.data();
  std::vector<double> b(pb.p0.begin() + pb.m * kCnp, pb.p0.end());
  double target[3] = {b[0] + 0.05, b[1], b[2]};
  pp = point_prior(0, target, sigma);
  sba_ext_options_init(&ext);
  ext.quiet = 1;
  ext.npoint_priors = 1;
  ext.point_priors = &pp;
  ASSERT_GT(sba_str_levmar_ext(pb.n, 0, pb.m, pb.vmask.data(), b.data(), kPnp, pb.x.data(), nullptr, kMnp,
                               synth::proj_str, synth::projac_str, &pb, 100, 0, nullptr, info, &ext),
            0);
  for (int q = 0; q < 3; ++q) EXPECT_LT(std::fabs(b[size_t(q)] - target[q]), 3e-4);
}

}  // namespace
