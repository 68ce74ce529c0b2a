// SPDX-License-Identifier: BSD-3-Clause
// The run-time choice of linear solver (sba_ext.h, SBA_LINSOLVER) on synthetic problems:
// every solver reaches chol's minimum, and the extension options behave as documented.
#include <dlfcn.h>
#include <gtest/gtest.h>
#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "sanitized.h"
#include "sba_ext.h"
#include "synth.h"

namespace {

using synth::kCnp;
using synth::kMnp;
using synth::kPnp;

const char *const kAllSolvers[] = {"chol", "ldlt", "bk", "lu", "qr", "qrnoq",
                                   "svd", "cg", "ldl-amd", "sparse-chol", "chol-lapack",
                                   "iterative-schur"};

struct Outcome {
  int ret = 0;
  double info[SBA_INFOSZ] = {};
  std::vector<double> p;
};

Outcome solve(synth::Problem &pb, const sba_ext_options *ext, int mcon = 0, int ncon = 0,
              bool simple = false) {
  Outcome o;
  o.p = pb.p0;
  if (simple)
    o.ret = sba_motstr_levmar_ext(pb.n, ncon, pb.m, mcon, pb.vmask.data(), o.p.data(), kCnp, kPnp,
                                  pb.x.data(), nullptr, kMnp, synth::proj_motstr, synth::projac_motstr,
                                  &pb, 200, 0, nullptr, o.info, ext);
  else
    o.ret = sba_motstr_levmar_x_ext(pb.n, ncon, pb.m, mcon, pb.vmask.data(), o.p.data(), kCnp, kPnp,
                                    pb.x.data(), nullptr, kMnp, synth::func_motstr, synth::fjac_motstr,
                                    &pb, 200, 0, nullptr, o.info, ext);
  return o;
}

Outcome solve_with(synth::Problem &pb, const char *solver, int mcon = 0, int ncon = 0) {
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = solver;
  return solve(pb, &ext, mcon, ncon);
}

class EverySolver : public ::testing::TestWithParam<const char *> {};

// mcon = 0: the 7-dimensional gauge freedom makes J^T J, and S, singular without damping.
TEST_P(EverySolver, ReachesCholsMinimumWithASingularUndampedS) {
  synth::Problem pb = synth::make(150, 8, 0.5, 0.05, 31);
  const Outcome ref = solve_with(pb, "chol");
  const Outcome o = solve_with(pb, GetParam());
  ASSERT_GT(ref.ret, 0);
  ASSERT_GT(o.ret, 0) << GetParam();
  EXPECT_NEAR(o.info[1] / ref.info[1], 1.0, 5e-7) << GetParam();
  EXPECT_EQ(o.info[0], ref.info[0]);
  EXPECT_GE(o.info[6], 1);
  EXPECT_LE(o.info[6], 5);
}

TEST_P(EverySolver, ReachesCholsMinimumWithFixedCamerasAndPoints) {
  synth::Problem pb = synth::make(120, 7, 0.3, 0.05, 32);
  const Outcome ref = solve_with(pb, "chol", 2, 5);
  const Outcome o = solve_with(pb, GetParam(), 2, 5);
  ASSERT_GT(o.ret, 0) << GetParam();
  EXPECT_NEAR(o.info[1] / ref.info[1], 1.0, 5e-7) << GetParam();
  // Fixed blocks stay put whatever the solver.
  for (int q = 0; q < 2 * kCnp; ++q) EXPECT_EQ(o.p[q], pb.p0[q]);
  for (int q = 0; q < 5 * kPnp; ++q) EXPECT_EQ(o.p[pb.m * kCnp + q], pb.p0[pb.m * kCnp + q]);
}

TEST_P(EverySolver, NoiseFreeDataReachesZero) {
  synth::Problem pb = synth::make(80, 6, 0.0, 0.05, 33);
  const Outcome o = solve_with(pb, GetParam());
  ASSERT_GT(o.ret, 0) << GetParam();
  EXPECT_LT(o.info[1] / pb.nvis, 1e-12) << GetParam();
}

// pb with camera j seeing no point: its projections taken out of vmask and x.
synth::Problem without_camera(synth::Problem pb, int j) {
  std::vector<double> x;
  size_t k = 0;
  for (int i = 0; i < pb.n; ++i)
    for (int c = 0; c < pb.m; ++c) {
      char &seen = pb.vmask[size_t(i) * pb.m + c];
      if (!seen) continue;
      if (c == j) {
        seen = 0;
        --pb.nvis;
      } else {
        x.insert(x.end(), pb.x.begin() + long(k), pb.x.begin() + long(k + kMnp));
      }
      k += kMnp;
    }
  pb.x = x;
  return pb;
}

// A camera that sees no point has no equations: only the damping sits on its rows of S, its
// right-hand side is zero, and so is its step. It comes back with the bits it went in with,
// whatever solves the step and whatever damps it, and the others' solve is not disturbed.
TEST_P(EverySolver, ACameraThatSeesNoPointKeepsItsBits) {
  const int lone = 3;
  synth::Problem pb = without_camera(synth::make(100, 7, 0.5, 0.05, 34, 0.9), lone);
  for (int i = 0; i < pb.n; ++i) {
    int seen = 0;
    for (int j = 0; j < pb.m; ++j) seen += pb.vmask[size_t(i) * pb.m + j];
    ASSERT_GE(seen, 2) << "point " << i;
  }
  for (const char *strategy : {"sba", "sba-clean-retry", "trust-region"}) {
    sba_ext_options ext;
    sba_ext_options_init(&ext);
    ext.linsolver = GetParam();
    ext.strategy = strategy;
    const Outcome o = solve(pb, &ext);
    ASSERT_GT(o.ret, 0) << GetParam() << " " << strategy;
    for (int c = 0; c < kCnp; ++c) {
      const size_t q = size_t(lone) * kCnp + c;
      EXPECT_EQ(std::memcmp(&o.p[q], &pb.p0[q], sizeof(double)), 0)
          << GetParam() << " " << strategy << ": parameter " << c << " moved from " << pb.p0[q] << " to " << o.p[q];
    }
    EXPECT_NE(o.p[0], pb.p0[0]) << GetParam() << " " << strategy;
    EXPECT_LT(o.info[1] / pb.nvis, 1.0) << GetParam() << " " << strategy;
  }
}

INSTANTIATE_TEST_SUITE_P(Solvers, EverySolver, ::testing::ValuesIn(kAllSolvers),
                         [](const ::testing::TestParamInfo<const char *> &info) {
                           std::string s = info.param;
                           for (char &c : s)
                             if (c == '-') c = '_';
                           return s;
                         });

// A long sequence of m cameras: each of the n points seen by 3 consecutive cameras, so S is
// banded; noise-free measurements.
synth::Problem banded(int n, int m, unsigned seed) {
  synth::Problem pb = synth::make(n, m, 0.5, 0.03, seed, 0.0);
  pb.vmask.assign(pb.vmask.size(), 0);
  for (int i = 0; i < pb.n; ++i)
    for (int d = 0; d < 3; ++d) pb.vmask[size_t(i) * pb.m + (i * (pb.m - 2) / pb.n + d)] = 1;
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
  return pb;
}

TEST(Solvers, SparseCholMatchesCholOnABandedProblem) {
  synth::Problem pb = banded(200, 30, 34);
  const Outcome ref = solve_with(pb, "chol", 1), sp = solve_with(pb, "sparse-chol", 1),
                la = solve_with(pb, "ldl-amd", 1);
  ASSERT_GT(ref.ret, 0);
  EXPECT_NEAR(sp.info[1], ref.info[1], 1e-6 * ref.info[1] + 1e-12);
  EXPECT_NEAR(la.info[1], ref.info[1], 1e-6 * ref.info[1] + 1e-12);
}

TEST(Solvers, UnknownNameInTheOptionsIsABadArgument) {
  synth::Problem pb = synth::make(40, 4, 0.1, 0.05, 35);
  testing::internal::CaptureStderr();
  const Outcome o = solve_with(pb, "cholesky");
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(o.ret, SBA_ERROR);
  EXPECT_EQ(o.info[6], SBA_STOP_NONE);
  EXPECT_NE(err.find("unknown linear solver \"cholesky\" (known: chol ldlt"), std::string::npos) << err;
  EXPECT_EQ(o.p, pb.p0);
}

// The legacy entry points read SBA_LINSOLVER: the solve is then the extension call's, bit
// for bit, and an unknown name falls back to chol with a message.
TEST(Solvers, EnvironmentVariableSwitchesTheLegacyEntryPoints) {
  synth::Problem pb = synth::make(100, 6, 0.4, 0.05, 36);
  const Outcome chol = solve_with(pb, "chol"), amd = solve_with(pb, "ldl-amd");
  ASSERT_NE(chol.p, amd.p);  // different arithmetic, different last bits
  auto legacy = [&] {
    Outcome o;
    o.p = pb.p0;
    o.ret = sba_motstr_levmar_x(pb.n, 0, pb.m, 0, pb.vmask.data(), o.p.data(), kCnp, kPnp, pb.x.data(),
                                nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 200, 0,
                                nullptr, o.info);
    return o;
  };
  ASSERT_EQ(setenv("SBA_LINSOLVER", "ldl-amd", 1), 0);
  const Outcome viaenv = legacy();
  EXPECT_EQ(viaenv.p, amd.p);
  ASSERT_EQ(setenv("SBA_LINSOLVER", "nonsense", 1), 0);
  testing::internal::CaptureStderr();
  const Outcome fallback = legacy();
  const std::string err = testing::internal::GetCapturedStderr();
  unsetenv("SBA_LINSOLVER");
  EXPECT_EQ(fallback.p, chol.p);
  EXPECT_NE(err.find("unknown SBA_LINSOLVER \"nonsense\""), std::string::npos) << err;
  EXPECT_NE(err.find("using chol"), std::string::npos) << err;
  // An explicit choice in the options wins over the environment.
  ASSERT_EQ(setenv("SBA_LINSOLVER", "ldl-amd", 1), 0);
  const Outcome explicit_chol = solve_with(pb, "chol");
  unsetenv("SBA_LINSOLVER");
  EXPECT_EQ(explicit_chol.p, chol.p);
}

// Every line a log sink receives, with its level.
struct Captured {
  std::vector<std::pair<int, std::string>> lines;
};
void capture(void *ctx, int level, const char *line) {
  static_cast<Captured *>(ctx)->lines.emplace_back(level, line);
}
// Default options whose log sink is c.
sba_ext_options logging_to(Captured *c) {
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.log = capture;
  ext.log_ctx = c;
  return ext;
}

// ---------------------------------------------------------------- single precision

// Options naming the solver and the strategy, with the Jacobian in single precision or not.
sba_ext_options precision_options(const char *solver, const char *strategy, bool single) {
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = solver;
  ext.strategy = strategy;
  ext.single_precision_jacobian = single;
  return ext;
}

// One simple-driver solve with those options.
Outcome solve_single(synth::Problem &pb, const char *solver, const char *strategy, bool single, int mcon = 0,
                     int ncon = 0) {
  const sba_ext_options ext = precision_options(solver, strategy, single);
  return solve(pb, &ext, mcon, ncon, true);
}

// The rounded Jacobian moves the steps, not the minimum: every solver that takes it ends at
// the cost of the same solve in double, with the fixed blocks untouched; the results differ
// from the double ones, so the single-precision blocks were what the solve read.
TEST(SinglePrecisionJacobian, ReachesTheMinimumOfTheSolveInDouble) {
  synth::Problem pb = synth::make(150, 8, 0.5, 0.05, 61);
  for (const char *solver : {"chol", "sparse-chol", "iterative-schur", "lu"})
    for (const char *strategy : {"sba", "trust-region"}) {
      SCOPED_TRACE(std::string(solver) + " " + strategy);
      const Outcome ref = solve_single(pb, solver, strategy, false, 2, 5);
      const Outcome o = solve_single(pb, solver, strategy, true, 2, 5);
      ASSERT_GT(ref.ret, 0);
      ASSERT_GT(o.ret, 0);
      EXPECT_NEAR(o.info[1] / ref.info[1], 1.0, 1e-9);
      // The initial error, summed point by point without the residual kept: the same to
      // rounding.
      EXPECT_NEAR(o.info[0] / ref.info[0], 1.0, 1e-14);
      EXPECT_NE(o.p, ref.p);
      for (int q = 0; q < 2 * kCnp; ++q) EXPECT_EQ(o.p[q], pb.p0[q]);
      for (int q = 0; q < 5 * kPnp; ++q) EXPECT_EQ(o.p[pb.m * kCnp + q], pb.p0[pb.m * kCnp + q]);
    }
}

// The same with measurement covariances, a robust loss and a Jacobian by differences, each
// of which the blocks go through in double before they are rounded.
TEST(SinglePrecisionJacobian, WeightsLossesAndDifferencesKeepTheMinimum) {
  synth::Problem pb = synth::make(150, 8, 0.5, 0.05, 63);
  std::vector<double> covx(pb.x.size() * kMnp);
  for (size_t k = 0; k < covx.size() / 4; ++k) {  // [a b; b c], positive definite
    const double a = 1.0 + 0.5 * std::sin(double(k)), c = 1.5 + 0.5 * std::cos(double(k)), b = 0.3 * std::sin(3.0 * k);
    covx[4 * k] = a, covx[4 * k + 1] = covx[4 * k + 2] = b, covx[4 * k + 3] = c;
  }
  enum Kind { kWeighted, kRobust, kDifferences };
  for (Kind kind : {kWeighted, kRobust, kDifferences})
    for (const char *strategy : {"sba", "trust-region"}) {
      SCOPED_TRACE(std::to_string(int(kind)) + " " + strategy);
      Outcome o[2];
      for (int single = 0; single < 2; ++single) {
        sba_ext_options ext = precision_options("chol", strategy, single);
        if (kind == kRobust) ext.loss = "huber";
        o[single].p = pb.p0;
        o[single].ret = sba_motstr_levmar_ext(pb.n, 0, pb.m, 1, pb.vmask.data(), o[single].p.data(), kCnp, kPnp,
                                              pb.x.data(), kind == kWeighted ? covx.data() : nullptr, kMnp,
                                              synth::proj_motstr, kind == kDifferences ? nullptr : synth::projac_motstr,
                                              &pb, 200, 0, nullptr, o[single].info, &ext);
        ASSERT_GT(o[single].ret, 0);
      }
      EXPECT_NEAR(o[1].info[1] / o[0].info[1], 1.0, 1e-9);
      EXPECT_NE(o[1].p, o[0].p);
    }
}

// A linear model, x_ij = C(i, j) (a_j, b_i) with coefficients no float holds: its least-squares
// minimum is where the gradient J^T e is zero, which the test can compute in double.
struct Linear {
  static constexpr int n = 40, m = 6;
  static double c(int i, int j, int r, int q) { return std::sin(1.3 * i + 2.1 * j + 0.7 * r + 0.37 * q) + 0.5; }
  static void proj(int j, int i, double *a, double *b, double *x, void *) {
    for (int r = 0; r < kMnp; ++r) {
      x[r] = 0.0;
      for (int q = 0; q < kCnp; ++q) x[r] += c(i, j, r, q) * a[q];
      for (int q = 0; q < kPnp; ++q) x[r] += c(i, j, r, kCnp + q) * b[q];
    }
  }
  static void projac(int j, int i, double *, double *, double *A, double *B, void *) {
    for (int r = 0; r < kMnp; ++r) {
      for (int q = 0; q < kCnp; ++q) A[r * kCnp + q] = c(i, j, r, q);
      for (int q = 0; q < kPnp; ++q) B[r * kPnp + q] = c(i, j, r, kCnp + q);
    }
  }
  // The largest entry of J^T (x - f(p)) over the free cameras (1..m-1) and points.
  static double gradient(const std::vector<double> &p, const std::vector<double> &x) {
    std::vector<double> g(p.size(), 0.0);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < m; ++j) {
        double f[kMnp];
        proj(j, i, const_cast<double *>(&p[size_t(j * kCnp)]), const_cast<double *>(&p[size_t(m * kCnp + i * kPnp)]), f,
             nullptr);
        for (int r = 0; r < kMnp; ++r) {
          const double e = x[size_t((i * m + j) * kMnp + r)] - f[r];
          for (int q = 0; q < kCnp; ++q) g[size_t(j * kCnp + q)] += c(i, j, r, q) * e;
          for (int q = 0; q < kPnp; ++q) g[size_t(m * kCnp + i * kPnp + q)] += c(i, j, r, kCnp + q) * e;
        }
      }
    double worst = 0.0;
    for (size_t q = kCnp; q < g.size(); ++q) worst = std::max(worst, std::fabs(g[q]));
    return worst;
  }
};

// The blocks are rounded, the gradient is not: on a linear problem the solve ends where the
// gradient in double is as small as the solve in double leaves it, where the cost stops
// changing, several times under the bound on every kernel build. With the gradient of
// the rounded blocks it would end where that one is zero, and the true gradient there, the
// roundings of this fixed J times the residual, lies several times above the bound.
TEST(SinglePrecisionJacobian, EndsWhereTheGradientInDoubleIsZero) {
  std::vector<char> vmask(size_t(Linear::n * Linear::m), 1);
  std::vector<double> x(size_t(Linear::n * Linear::m * kMnp)), p0(size_t(Linear::m * kCnp + Linear::n * kPnp));
  for (size_t k = 0; k < x.size(); ++k) x[k] = 10.0 * std::cos(0.9 * double(k));
  for (size_t k = 0; k < p0.size(); ++k) p0[k] = std::sin(double(k));
  double worst[2];
  for (int single = 0; single < 2; ++single) {
    const sba_ext_options ext = precision_options("chol", "sba", single);
    std::vector<double> p = p0;
    double info[SBA_INFOSZ];
    ASSERT_GT(sba_motstr_levmar_ext(Linear::n, 0, Linear::m, 1, vmask.data(), p.data(), kCnp, kPnp, x.data(), nullptr,
                                    kMnp, Linear::proj, Linear::projac, nullptr, 100, 0, nullptr, info, &ext),
              0);
    worst[single] = Linear::gradient(p, x);
  }
  EXPECT_LT(worst[0], 2e-7);
  EXPECT_LT(worst[1], 2e-7);
}

// Where it cannot serve, the call fails with a reason rather than storing doubles silently:
// an expert driver (its fjac fills a whole double Jacobian), ldl-amd, shared parameters.
// The heap a solve holds at its largest, sampled after every iteration (glibc's count of the
// bytes in use, the blocks malloc maps included), less what was in use before the call.
struct HeapPeak {
  size_t base = 0, peak = 0;
  static size_t in_use() {
    const struct mallinfo2 mi = mallinfo2();
    return mi.uordblks + mi.hblkhd;
  }
  static int sample(void *ctx, const sba_progress *) {
    auto *h = static_cast<HeapPeak *>(ctx);
    h->peak = std::max(h->peak, in_use());
    return 0;
  }
};

// Bytes per observation that a simple-driver solve with iterative-schur holds (2 threads).
double solve_bytes_per_observation(synth::Problem &pb, bool single, const char *loss) {
  sba_ext_options ext = precision_options("iterative-schur", "trust-region", single);
  ext.nthreads = 2;
  ext.loss = loss;
  HeapPeak h;
  ext.progress = HeapPeak::sample;
  ext.progress_ctx = &h;
  std::vector<double> p = pb.p0;
  double info[SBA_INFOSZ];
  h.base = HeapPeak::in_use();
  const int ret = sba_motstr_levmar_ext(pb.n, 0, pb.m, 1, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(), nullptr,
                                        kMnp, synth::proj_motstr, synth::projac_motstr, &pb, 5, 0, nullptr, info, &ext);
  EXPECT_GT(ret, 0);
  return double(h.peak - h.base) / pb.nvis;
}

// With the Jacobian in single precision a simple-driver solve keeps, per observation, the
// blocks in floats and the point-major index, and nothing else: the residual is summed point by
// point and made again beside the blocks (with a robust loss too), and the index's val array
// is not kept. Points and cameras hold the rest (a few hundred bytes a point; a camera's
// partial sums, 32 chunks' worth), under 12 bytes an observation with 80 cameras and 2,000
// points all seen by all: the 4 bytes of val or the 16 of the residual would not fit. The
// solve in double holds its Jacobian (twice the blocks' bytes) and the residual besides.
TEST(SinglePrecisionJacobian, KeepsTheBlocksInFloatsAndLittleElse) {
#ifdef SBA_TEST_SANITIZED
  GTEST_SKIP() << "the sanitizer's allocator keeps its own count";
#endif
  synth::Problem pb = synth::make(2000, 80, 0.5, 0.02, 67, 1.0);
  ASSERT_EQ(pb.nvis, 160000);
  const double blocks = double(sizeof(float)) * kMnp * (kCnp + kPnp);
  for (const char *loss : {"none", "cauchy"}) {
    SCOPED_TRACE(loss);
    const double single = solve_bytes_per_observation(pb, true, loss);
    const double dbl = solve_bytes_per_observation(pb, false, loss);
    EXPECT_LE(single, blocks + sizeof(int) + 12);
    EXPECT_GE(dbl, 2 * blocks + kMnp * sizeof(double) + sizeof(int));
  }
}

TEST(SinglePrecisionJacobian, RefusedWhereItCannotServe) {
  synth::Problem pb = synth::make(60, 5, 0.5, 0.05, 62);
  std::vector<int> group(size_t(pb.m), 0);
  const char shared[kCnp] = {0, 0, 0, 0, 0, 1};
  const struct {
    bool simple;
    const char *solver;
    bool share;
    const char *says;
  } cases[] = {{false, "chol", false, "simple drivers"},
               {true, "ldl-amd", false, "ldl-amd"},
               {true, "chol", true, "shared camera parameters"}};
  for (const auto &c : cases) {
    SCOPED_TRACE(c.says);
    Captured log;
    sba_ext_options ext = logging_to(&log);
    ext.linsolver = c.solver;
    ext.single_precision_jacobian = 1;
    if (c.share) {
      ext.cam_group = group.data();
      ext.cam_shared = shared;
    }
    const Outcome o = solve(pb, &ext, 0, 0, c.simple);
    EXPECT_EQ(o.ret, SBA_ERROR);
    EXPECT_EQ(o.info[6], SBA_STOP_NONE);
    EXPECT_EQ(o.p, pb.p0);
    ASSERT_FALSE(log.lines.empty());
    EXPECT_NE(log.lines.back().second.find(c.says), std::string::npos) << log.lines.back().second;
    ext.single_precision_jacobian = 0;
    EXPECT_GT(solve(pb, &ext, 0, 0, c.simple).ret, 0);
  }
}

// ---------------------------------------------------------------- auto

// One solve of at most itmax iterations by the expert extension driver with `solver` (null:
// none named), reporting into *res.
Outcome solve_reported(synth::Problem &pb, const char *solver, int itmax, sba_ext_result *res) {
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  sba_ext_result_init(res);
  ext.linsolver = solver;
  ext.result = res;
  Outcome o;
  o.p = pb.p0;
  o.ret = sba_motstr_levmar_x_ext(pb.n, 0, pb.m, 1, pb.vmask.data(), o.p.data(), kCnp, kPnp, pb.x.data(), nullptr,
                                  kMnp, synth::func_motstr, synth::fjac_motstr, &pb, itmax, 0, nullptr, o.info, &ext);
  return o;
}

TEST(AutoSolver, IsANameOfTheList) {
  EXPECT_EQ(sba_linsolver_valid("auto"), 1);
  const std::string names = std::string(" ") + sba_linsolver_names() + " ";
  EXPECT_NE(names.find(" auto "), std::string::npos) << names;
}

// One problem of each regime (docs/solvers.md): auto runs the solver the rule picks for it,
// says which in the result, and gives that solver's bits.
TEST(AutoSolver, PicksBySizeAndSparsityAndGivesThatSolversBits) {
  const struct {
    const char *what;
    synth::Problem pb;
    const char *expected;
  } cases[] = {
      {"8 cameras", synth::make(60, 8, 0.5, 0.05, 41), "chol"},
      // 1194 camera unknowns (one camera fixed), S banded.
      {"a sequence of 200 cameras", banded(600, 200, 42), "sparse-chol"},
      // 1194 camera unknowns, each point seen by about 10 of the 200 cameras: S dense.
      {"200 cameras seeing each other", synth::make(2000, 200, 0.5, 0.03, 43, 0.05), "iterative-schur"},
  };
  for (auto c : cases) {
    sba_ext_result by_auto, by_name;
    const Outcome a = solve_reported(c.pb, "auto", 3, &by_auto);
    const Outcome e = solve_reported(c.pb, c.expected, 3, &by_name);
    ASSERT_GT(a.ret, 0) << c.what;
    ASSERT_NE(by_auto.linsolver, nullptr) << c.what;
    EXPECT_STREQ(by_auto.linsolver, c.expected) << c.what;
    EXPECT_STREQ(by_name.linsolver, c.expected) << c.what;
    EXPECT_EQ(a.ret, e.ret) << c.what;
    EXPECT_EQ(a.p, e.p) << c.what;
    for (int k = 0; k < SBA_INFOSZ; ++k) EXPECT_EQ(a.info[k], e.info[k]) << c.what << " info[" << k << "]";
  }
}

// What no name means: sba 1.6's chol for the 1.6 entry points and an _ext call without ext;
// auto for an _ext call given options and for the pairs entry points; SBA_LINSOLVER before
// either.
TEST(AutoSolver, DefaultByEntryPoint) {
  synth::Problem pb = banded(600, 200, 44);
  sba_ext_result res;
  const Outcome chol = solve_reported(pb, "chol", 2, &res), sparse = solve_reported(pb, "sparse-chol", 2, &res);
  ASSERT_GT(chol.ret, 0);
  ASSERT_NE(chol.p, sparse.p);  // different arithmetic, different last bits
  const auto legacy = [&] {
    std::vector<double> p = pb.p0;
    sba_motstr_levmar_x(pb.n, 0, pb.m, 1, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(), nullptr, kMnp,
                        synth::func_motstr, synth::fjac_motstr, &pb, 2, 0, nullptr, nullptr);
    return p;
  };
  const auto null_ext = [&] {
    std::vector<double> p = pb.p0;
    sba_motstr_levmar_x_ext(pb.n, 0, pb.m, 1, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(), nullptr, kMnp,
                            synth::func_motstr, synth::fjac_motstr, &pb, 2, 0, nullptr, nullptr, nullptr);
    return p;
  };
  std::vector<int> point, camera;
  for (int i = 0; i < pb.n; ++i)
    for (int j = 0; j < pb.m; ++j)
      if (pb.vmask[size_t(i) * pb.m + j]) point.push_back(i), camera.push_back(j);
  const sba_visibility vis{static_cast<long long>(point.size()), point.data(), camera.data()};
  const auto pairs = [&] {
    std::vector<double> p = pb.p0;
    sba_motstr_levmar_x_vis(pb.n, 0, pb.m, 1, &vis, p.data(), kCnp, kPnp, pb.x.data(), nullptr, kMnp,
                            synth::func_motstr, synth::fjac_motstr, &pb, 2, 0, nullptr, nullptr, nullptr);
    return p;
  };
  unsetenv("SBA_LINSOLVER");
  EXPECT_EQ(legacy(), chol.p);
  EXPECT_EQ(null_ext(), chol.p);
  EXPECT_EQ(pairs(), sparse.p);
  const Outcome unnamed = solve_reported(pb, nullptr, 2, &res);
  EXPECT_EQ(unnamed.p, sparse.p);
  EXPECT_STREQ(res.linsolver, "sparse-chol");
  // SBA_LINSOLVER=auto gives the 1.6 entry points the choice; a name there wins over auto.
  ASSERT_EQ(setenv("SBA_LINSOLVER", "auto", 1), 0);
  EXPECT_EQ(legacy(), sparse.p);
  ASSERT_EQ(setenv("SBA_LINSOLVER", "chol", 1), 0);
  EXPECT_EQ(pairs(), chol.p);
  EXPECT_EQ(solve_reported(pb, nullptr, 2, &res).p, chol.p);
  EXPECT_STREQ(res.linsolver, "chol");
  // A name it does not know is said, and the entry point's own default used.
  ASSERT_EQ(setenv("SBA_LINSOLVER", "nonsense", 1), 0);
  testing::internal::CaptureStderr();
  const Outcome fallback = solve_reported(pb, nullptr, 2, &res);
  const std::vector<double> legacy_fallback = legacy();
  const std::string err = testing::internal::GetCapturedStderr();
  unsetenv("SBA_LINSOLVER");
  EXPECT_EQ(fallback.p, sparse.p);
  EXPECT_STREQ(res.linsolver, "sparse-chol");
  EXPECT_EQ(legacy_fallback, chol.p);
  // (The _ext entry points are named as their 1.6 counterparts in messages.)
  EXPECT_NE(err.find("sba_motstr_levmar_x: unknown SBA_LINSOLVER \"nonsense\" (known: " +
                     std::string(sba_linsolver_names()) + "); using auto\n"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("sba_motstr_levmar_x: unknown SBA_LINSOLVER \"nonsense\" (known: " +
                     std::string(sba_linsolver_names()) + "); using chol\n"),
            std::string::npos)
      << err;
}

// Verbose, the choice is said with the numbers it was made from; not verbose, nothing is.
TEST(AutoSolver, VerboseSaysWhatItChoseAndWhy) {
  synth::Problem pb = banded(600, 200, 45);
  for (int verbose : {0, 1}) {
    Captured log;
    const sba_ext_options ext = logging_to(&log);
    std::vector<double> p = pb.p0;
    ASSERT_GT(sba_motstr_levmar_x_ext(pb.n, 0, pb.m, 1, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(), nullptr,
                                      kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 1, verbose, nullptr, nullptr,
                                      &ext),
              0);
    const auto said = std::find_if(log.lines.begin(), log.lines.end(), [](const std::pair<int, std::string> &l) {
      return l.second.find("linear solver auto") != std::string::npos;
    });
    if (verbose == 0) {
      EXPECT_EQ(said, log.lines.end());
      continue;
    }
    ASSERT_NE(said, log.lines.end());
    const std::string &line = said->second;
    EXPECT_EQ(said->first, SBA_LOG_INFO);
    EXPECT_EQ(line.rfind("sba_motstr_levmar_x: linear solver auto: sparse-chol (S of 1194 unknowns in 199 blocks, ", 0),
              0u)
        << line;
    EXPECT_NE(line.find(" passes over the Jacobian of 1800 observations and forming it 12; MiB besides the common "),
              std::string::npos)
        << line;
  }
}

// ---------------------------------------------------------------- log sink, quiet, progress

TEST(ExtOptions, LogSinkReceivesErrorsAndProgress) {
  synth::Problem pb = synth::make(40, 4, 0.1, 0.05, 37);
  Captured c;
  const sba_ext_options ext = logging_to(&c);
  std::vector<double> p = pb.p0;
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  int ret = sba_motstr_levmar_x_ext(pb.n, 0, pb.m, 0, pb.vmask.data(), p.data(), kCnp, kPnp, pb.x.data(),
                                    nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 100, 2,
                                    nullptr, nullptr, &ext);
  ret = std::min(ret, sba_motstr_levmar_x_ext(pb.n, 0, pb.m, pb.m + 3, pb.vmask.data(), p.data(), kCnp,
                                              kPnp, pb.x.data(), nullptr, kMnp, synth::func_motstr,
                                              synth::fjac_motstr, &pb, 100, 0, nullptr, nullptr, &ext));
  EXPECT_EQ(testing::internal::GetCapturedStdout(), "");
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
  EXPECT_EQ(ret, SBA_ERROR);
  ASSERT_GE(c.lines.size(), 5u);
  // What auto chose (this ext names no solver), then 1.6's line, then the library's own, which
  // only a sink receives.
  EXPECT_EQ(c.lines[0].first, SBA_LOG_INFO);
  EXPECT_EQ(c.lines[0].second.rfind("sba_motstr_levmar_x: linear solver auto: chol (S of 24 unknowns in 4 blocks", 0),
            0u)
      << c.lines[0].second;
  EXPECT_EQ(c.lines[1].first, SBA_LOG_INFO);
  EXPECT_EQ(c.lines[1].second.rfind("initial motstr-SBA error ", 0), 0u) << c.lines[1].second;
  EXPECT_EQ(c.lines[2].first, SBA_LOG_INFO);
  EXPECT_EQ(c.lines[2].second.rfind("SBA: initial error ", 0), 0u) << c.lines[2].second;
  EXPECT_EQ(c.lines.back().first, SBA_LOG_ERROR);
  EXPECT_NE(c.lines.back().second.find("mcon must be in [0, m]"), std::string::npos);
}

TEST(ExtOptions, QuietPrintsNothingEvenForErrors) {
  synth::Problem pb = synth::make(40, 4, 0.1, 0.05, 38);
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.quiet = 1;
  std::vector<double> p = pb.p0;
  double info[SBA_INFOSZ];
  testing::internal::CaptureStderr();
  const int ret = sba_motstr_levmar_x_ext(-1, 0, pb.m, 0, pb.vmask.data(), p.data(), kCnp, kPnp,
                                          pb.x.data(), nullptr, kMnp, synth::func_motstr,
                                          synth::fjac_motstr, &pb, 100, 3, nullptr, info, &ext);
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
  EXPECT_EQ(ret, SBA_ERROR);
  EXPECT_EQ(info[6], SBA_STOP_NONE);
}

struct Progress {
  int calls = 0, stop_at = 0;
  std::vector<double> errors;
  double last_elapsed = -1;
  bool elapsed_monotone = true;
};
int on_progress(void *ctx, const sba_progress *s) {
  Progress &pr = *static_cast<Progress *>(ctx);
  ++pr.calls;
  EXPECT_EQ(s->iteration, pr.calls);
  pr.errors.push_back(s->error);
  if (s->elapsed < pr.last_elapsed) pr.elapsed_monotone = false;
  pr.last_elapsed = s->elapsed;
  return pr.calls == pr.stop_at;
}

TEST(ExtOptions, ProgressCallbackSeesEveryIterationAndCanStop) {
  synth::Problem pb = synth::make(100, 6, 0.5, 0.1, 39);
  Progress all;
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.progress = on_progress;
  ext.progress_ctx = &all;
  const Outcome full = solve(pb, &ext);
  ASSERT_GT(full.ret, 3);
  // Called after every iteration, the one that stopped the solve included.
  EXPECT_EQ(all.calls, full.ret);
  EXPECT_TRUE(all.elapsed_monotone);
  for (size_t q = 1; q < all.errors.size(); ++q) EXPECT_LE(all.errors[q], all.errors[q - 1]);

  Progress early;
  early.stop_at = 2;
  ext.progress_ctx = &early;
  const Outcome stopped = solve(pb, &ext, 0, 0, true);
  EXPECT_EQ(stopped.ret, 2);
  EXPECT_EQ(stopped.info[6], SBA_STOP_USER);
  EXPECT_EQ(stopped.info[1], early.errors.back());
  EXPECT_NEAR(synth::sq_error(pb, stopped.p.data()), stopped.info[1], 1e-9 * stopped.info[1]);
}

// A caller compiled against an older, shorter sba_ext_options: the fields it does not know
// keep their defaults.
TEST(ExtOptions, ShorterStructFromAnOlderCallerIsHonoured) {
  synth::Problem pb = synth::make(40, 4, 0.1, 0.05, 40);
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = "ldl-amd";
  ext.quiet = 1;  // beyond the declared size: must be ignored
  ext.size = offsetof(sba_ext_options, log);
  const Outcome o = solve(pb, &ext);
  const Outcome amd = solve_with(pb, "ldl-amd");
  EXPECT_EQ(o.p, amd.p);
  testing::internal::CaptureStderr();
  ext.linsolver = "x";
  const Outcome bad2 = solve(pb, &ext);
  EXPECT_NE(testing::internal::GetCapturedStderr(), "");  // quiet was not read
  EXPECT_EQ(bad2.ret, SBA_ERROR);
}

}  // namespace

namespace {

// The threads split the work by fixed rules and every sum has a fixed order: the same bits
// for any thread count, with every solver, with fixed cameras and points too.
// nthreads 0 without SBA_NUM_THREADS: every hardware thread, but one per 10,000 projections
// at most; a count that is asked for (in the options or the environment) is used as given.
TEST(ExtOptions, DefaultThreadCountFollowsTheProblemSize) {
  unsetenv("SBA_NUM_THREADS");
  auto threads_used = [](synth::Problem &pb, int nthreads) {
    sba_ext_options ext;
    sba_ext_options_init(&ext);
    ext.nthreads = nthreads;
    sba_ext_result res;
    sba_ext_result_init(&res);
    ext.result = &res;
    std::vector<double> p = pb.p0;
    double info[SBA_INFOSZ];
    const int ret = sba_motstr_levmar_x_ext(pb.n, 0, pb.m, 1, pb.vmask.data(), p.data(), kCnp, kPnp,
                                            pb.x.data(), nullptr, kMnp, synth::func_motstr,
                                            synth::fjac_motstr, &pb, 1, 0, nullptr, info, &ext);
    EXPECT_NE(ret, SBA_ERROR);
    return res.nthreads;
  };
  const int hw = std::max(1, int(std::thread::hardware_concurrency()));
  synth::Problem small = synth::make(600, 8, 0.5, 0.05, 43);  // ~3,400 projections
  ASSERT_LT(small.nvis, 10000);
  EXPECT_EQ(threads_used(small, 0), 1);
  EXPECT_EQ(threads_used(small, 3), 3);
  ASSERT_EQ(setenv("SBA_NUM_THREADS", "2", 1), 0);
  EXPECT_EQ(threads_used(small, 0), 2);
  unsetenv("SBA_NUM_THREADS");
  synth::Problem large = synth::make(4000, 8, 0.5, 0.05, 44, 0.9);  // ~29,000 projections
  ASSERT_GE(large.nvis, 20000);
  EXPECT_EQ(threads_used(large, 0), std::min(hw, int(large.nvis / 10000)));
}

TEST_P(EverySolver, ResultsDoNotDependOnTheThreadCount) {
  synth::Problem pb = synth::make(160, 9, 0.5, 0.05, 41);
  auto with_threads = [&](int threads) {
    sba_ext_options ext;
    sba_ext_options_init(&ext);
    ext.linsolver = GetParam();
    ext.nthreads = threads;
    return solve(pb, &ext, 1, 3);
  };
  const Outcome one = with_threads(1);
  ASSERT_GT(one.ret, 0);
  for (int threads : {2, 3, 5}) {
    const Outcome o = with_threads(threads);
    EXPECT_EQ(o.ret, one.ret) << threads;
    EXPECT_EQ(o.p, one.p) << GetParam() << " with " << threads << " threads";
    for (int q = 0; q < SBA_INFOSZ; ++q) EXPECT_EQ(o.info[q], one.info[q]) << q;
  }
}

// The dense S of `chol` is factored by the library's own Cholesky (up to 2048 unknowns), so
// the result does not depend on how many threads the BLAS runs either: with OpenBLAS's
// DPOTRF, 1 and 2 BLAS threads round differently and the solves can take different steps.
TEST(CholSolver, ResultsDoNotDependOnTheBlasThreads) {
  using SetThreads = void (*)(int);
  using GetThreads = int (*)();
  const auto set = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
  const auto get = reinterpret_cast<GetThreads>(dlsym(RTLD_DEFAULT, "openblas_get_num_threads"));
  if (!set || !get) GTEST_SKIP() << "the BLAS is not OpenBLAS: its thread count cannot be set";
  const int blas_default = get();
  synth::Problem pb = synth::make(1500, 60, 0.5, 0.05, 45, 0.3);
  auto run = [&](int threads, int blas_threads) {
    set(blas_threads);
    sba_ext_options ext;
    sba_ext_options_init(&ext);
    ext.linsolver = "chol";
    ext.nthreads = threads;
    return solve(pb, &ext, 1, 0);
  };
  const Outcome one = run(1, 1);
  ASSERT_GT(one.ret, 0);
  EXPECT_GT(one.info[5], 3);
  for (int threads : {1, 2})
    for (int blas : {1, 2}) {
      if (threads == 1 && blas == 1) continue;
      const Outcome o = run(threads, blas);
      EXPECT_EQ(o.p, one.p) << threads << " threads, " << blas << " BLAS threads";
      for (int q = 0; q < SBA_INFOSZ; ++q) EXPECT_EQ(o.info[q], one.info[q]) << q;
    }
  set(blas_default);
}

}  // namespace

namespace {

// Callbacks called concurrently (parallel_callbacks) compute exactly what the serial calls
// compute: the same bits, for both driver kinds, analytic and finite-difference Jacobians,
// and the simple drivers with the Jacobian in single precision (with a robust loss, whose
// residuals are then summed and made again chunk by chunk); and they are really called from
// more than one thread (and only then). The pool's caller, done with its part of a job, does
// the parts of workers that have not begun theirs, so on a busy machine a worker may not get
// to call one: the caller's calls wait (for at most a few seconds) until every thread asked
// for has made one, while the workers' parts of that job are still theirs.
struct SeenThreads {
  const synth::Problem *pb;
  std::thread::id caller = std::this_thread::get_id();
  size_t want = 1;
  std::mutex mu;
  std::set<std::thread::id> ids;
  void note() {
    std::unique_lock<std::mutex> lock(mu);
    ids.insert(std::this_thread::get_id());
    if (std::this_thread::get_id() != caller) return;
    for (int k = 0; k < 5000 && ids.size() < want; ++k) {
      lock.unlock();
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      lock.lock();
    }
  }
};
void seen_func(double *p, sba_crsm *idx, int *r, int *c, double *hx, void *ad) {
  static_cast<SeenThreads *>(ad)->note();
  synth::func_motstr(p, idx, r, c, hx, const_cast<synth::Problem *>(static_cast<SeenThreads *>(ad)->pb));
}
void seen_fjac(double *p, sba_crsm *idx, int *r, int *c, double *jac, void *ad) {
  static_cast<SeenThreads *>(ad)->note();
  synth::fjac_motstr(p, idx, r, c, jac, const_cast<synth::Problem *>(static_cast<SeenThreads *>(ad)->pb));
}
void seen_proj(int j, int i, double *a, double *b, double *x, void *ad) {
  static_cast<SeenThreads *>(ad)->note();
  synth::proj_motstr(j, i, a, b, x, nullptr);
}
void seen_projac(int j, int i, double *a, double *b, double *A, double *B, void *ad) {
  static_cast<SeenThreads *>(ad)->note();
  synth::projac_motstr(j, i, a, b, A, B, nullptr);
}

TEST(ParallelCallbacks, SameBitsAsSerialCallsForEveryDriverKind) {
  synth::Problem pb = synth::make(150, 8, 0.5, 0.05, 42);
  for (int kind = 0; kind < 3; ++kind)
    for (bool analytic : {true, false}) {
      const bool simple = kind > 0, single = kind == 2;
      auto run = [&](int threads, int parallel, size_t *nthreads_seen) {
        sba_ext_options ext;
        sba_ext_options_init(&ext);
        ext.nthreads = threads;
        ext.parallel_callbacks = parallel;
        ext.single_precision_jacobian = single;
        if (single) ext.loss = "cauchy";
        SeenThreads seen;
        seen.pb = &pb;
        seen.want = parallel ? size_t(threads) : 1;
        Outcome o;
        o.p = pb.p0;
        if (simple)
          o.ret = sba_motstr_levmar_ext(pb.n, 2, pb.m, 1, pb.vmask.data(), o.p.data(), kCnp, kPnp,
                                        pb.x.data(), nullptr, kMnp, seen_proj,
                                        analytic ? seen_projac : nullptr, &seen, 100, 0,
                                        nullptr, o.info, &ext);
        else
          o.ret = sba_motstr_levmar_x_ext(pb.n, 2, pb.m, 1, pb.vmask.data(), o.p.data(), kCnp, kPnp,
                                          pb.x.data(), nullptr, kMnp, seen_func,
                                          analytic ? seen_fjac : nullptr, &seen, 100, 0,
                                          nullptr, o.info, &ext);
        *nthreads_seen = seen.ids.size();
        return o;
      };
      const std::string what = std::string(!simple ? "expert" : single ? "simple single" : "simple") +
                               (analytic ? " analytic" : " fd");
      size_t seen = 0;
      const Outcome serial = run(1, 0, &seen);
      ASSERT_GT(serial.ret, 0);
      EXPECT_EQ(seen, 1u) << what;
      // Threads without the opt-in: still only the caller's thread.
      const Outcome unasked = run(3, 0, &seen);
      EXPECT_EQ(seen, 1u) << what;
      EXPECT_EQ(unasked.p, serial.p) << what;
      for (int threads : {2, 3}) {
        const Outcome par = run(threads, 1, &seen);
        EXPECT_EQ(seen, size_t(threads)) << what << " with " << threads << " threads";
        EXPECT_EQ(par.ret, serial.ret);
        EXPECT_EQ(par.p, serial.p) << what << " with " << threads << " threads";
        for (int q = 0; q < SBA_INFOSZ; ++q) EXPECT_EQ(par.info[q], serial.info[q]) << q;
      }
    }
}

}  // namespace

namespace {

// The AVX2+FMA build of the block kernels (chosen on CPUs that have them) and the portable
// one round differently but solve the same problem: the same minimum.
TEST(Kernels, PortableAndCpuSpecificBuildsReachTheSameMinimum) {
  synth::Problem pb = synth::make(150, 8, 0.5, 0.05, 43);
  const Outcome native = solve_with(pb, "chol");
  ASSERT_EQ(setenv("SBA_KERNELS", "portable", 1), 0);
  const Outcome portable = solve_with(pb, "chol");
  unsetenv("SBA_KERNELS");
  ASSERT_GT(native.ret, 0);
  ASSERT_GT(portable.ret, 0);
  EXPECT_NEAR(portable.info[1] / native.info[1], 1.0, 1e-10);
  for (size_t q = 0; q < native.p.size(); ++q) EXPECT_NEAR(portable.p[q], native.p[q], 1e-6) << q;
}

}  // namespace
