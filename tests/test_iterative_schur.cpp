// SPDX-License-Identifier: BSD-3-Clause
// The implicit-Schur CG solver (src/solver_iterative_schur.cpp) on random normal equations
// with fixed cameras and points: its S x against the explicitly assembled S, its step against
// the dense Cholesky step, the model reduction LM computes for its inexact step, the same bits
// for any thread count, and inputs it must refuse.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "camera_unknowns.h"
#include "layout.h"
#include "kernels.h"
#include "parallel.h"
#include "step_solver.h"

namespace {

using sba::i64;

// Every point seen by 2-8 of m cameras at random (most camera pairs share points, as in a
// photo collection), a random Jacobian and residual; the first mcon cameras and ncon points
// fixed. The normal equations are made by the library's kernels.
struct Problem {
  sba::Layout lay;
  std::vector<double> jac, e, U, V, ea, eb;

  Problem(int n, int m, int mcon, int ncon, int cnp, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> len(2, 8), cam(0, m - 1);
    std::normal_distribution<double> g(0.0, 1.0);
    std::vector<char> vmask(size_t(n) * size_t(m), 0);
    for (int i = 0; i < n; ++i)
      for (int l = len(rng); l > 0;) {
        char &c = vmask[size_t(i) * size_t(m) + size_t(cam(rng))];
        if (!c) c = 1, --l;
      }
    std::string msg;
    EXPECT_TRUE(sba::build_layout(lay, sba::Mode::MotStr, n, m, mcon, ncon, cnp, 3, 2, vmask.data(), &msg)) << msg;
    jac.resize(size_t(lay.nvis * lay.jblk()));
    e.resize(size_t(lay.nvis * 2));
    // Columns of very different scales, as camera parameters have.
    for (i64 k = 0; k < lay.nvis; ++k)
      for (int q = 0; q < lay.jblk(); ++q)
        jac[size_t(k * lay.jblk() + q)] = g(rng) * std::pow(10.0, double(q % (cnp + 3) % 4) - 1.0);
    for (double &v : e) v = g(rng);
    U.resize(size_t(m * cnp * cnp));
    ea.resize(size_t(m * cnp));
    V.resize(size_t(n * 9));
    eb.resize(size_t(n * 3));
    sba::ThreadPool pool(1);
    sba::make_kernels(lay, 1)->normal_equations(pool, jac.data(), e.data(), U.data(), V.data(), ea.data(), eb.data());
  }
  sba::NormalEquations ne() const { return {jac.data(), U.data(), V.data(), ea.data(), eb.data()}; }
  i64 nS() const { return i64(lay.free_cams()) * lay.cnp; }
};

// The step of `kind` at damping mu.
std::vector<double> step(const Problem &pb, sba::LinSolver kind, int threads, double mu, bool *ok = nullptr) {
  sba::ThreadPool pool(threads);
  const auto kernels = sba::make_kernels(pb.lay, pool.size());
  const auto solver = sba::make_step_solver(kind, sba::SolveContext{pb.lay, pool, *kernels});
  std::vector<double> dp(size_t(pb.lay.nvars()), -1.0);
  const bool solved = solver->solve(pb.ne(), mu, dp.data()) == sba::StepStatus::Solved;
  if (ok) *ok = solved;
  return dp;
}

// The explicitly assembled S at damping mu, both triangles (nS x nS, row-major), and its
// right-hand side into rhs (unless null).
std::vector<double> assembled_S(const Problem &pb, sba::ThreadPool &pool, const sba::Kernels &kernels, double mu,
                                std::vector<double> *rhs_out = nullptr) {
  const i64 nS = pb.nS();
  std::vector<double> S(static_cast<size_t>(nS * nS), 0.0), rhs(static_cast<size_t>(nS));
  sba::BlockMap dense;
  dense.base = S.data();
  dense.ld = nS;
  dense.cnp = pb.lay.cnp;
  EXPECT_TRUE(kernels.assemble(pool, pb.ne(), nullptr, mu, dense, rhs.data()));
  for (i64 r = 0; r < nS; ++r)  // the assembly fills the upper triangle
    for (i64 c = 0; c < r; ++c) S[size_t(r * nS + c)] = S[size_t(c * nS + r)];
  if (rhs_out) *rhs_out = rhs;
  return S;
}

class IterativeSchur : public ::testing::TestWithParam<int> {};

// S x from the blocks equals the assembled S times x to rounding, for every free camera.
TEST_P(IterativeSchur, ProductEqualsTheExplicitS) {
  const int cnp = GetParam();
  const Problem pb(400, 15, 2, 7, cnp, 11u + unsigned(cnp));
  const double mu = 0.3;
  const i64 nS = pb.nS();
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    sba::ThreadPool pool(threads);
    const auto kernels = sba::make_kernels(pb.lay, pool.size());
    const std::vector<double> S = assembled_S(pb, pool, *kernels, mu);
    std::vector<double> x(static_cast<size_t>(nS)), y(static_cast<size_t>(nS));
    for (i64 r = 0; r < nS; ++r) x[size_t(r)] = std::sin(double(r) + 0.5) * std::pow(10.0, double(r % 3) - 1.0);
    ASSERT_TRUE(
        sba::iterative_schur_product(sba::SolveContext{pb.lay, pool, *kernels}, pb.ne(), mu, x.data(), y.data()));
    double worst = 0.0;
    for (i64 r = 0; r < nS; ++r) {
      double want = 0.0, scale = 0.0;
      for (i64 c = 0; c < nS; ++c) {
        want += S[size_t(r * nS + c)] * x[size_t(c)];
        scale += std::fabs(S[size_t(r * nS + c)] * x[size_t(c)]);
      }
      worst = std::max(worst, std::fabs(y[size_t(r)] - want) / scale);
    }
    EXPECT_LT(worst, 1e-12);
  }
}

// The preconditioner's blocks, multiplied out from their Cholesky factors, are S's diagonal
// blocks to rounding.
TEST_P(IterativeSchur, PreconditionerIsTheDiagonalOfS) {
  const int cnp = GetParam();
  const Problem pb(400, 15, 2, 7, cnp, 13u + unsigned(cnp));
  const double mu = 0.3;
  const i64 nS = pb.nS(), nc = pb.lay.free_cams();
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    sba::ThreadPool pool(threads);
    const auto kernels = sba::make_kernels(pb.lay, pool.size());
    const std::vector<double> S = assembled_S(pb, pool, *kernels, mu);
    std::vector<double> D(static_cast<size_t>(nc * cnp * cnp), 0.0);
    ASSERT_TRUE(sba::iterative_schur_preconditioner(sba::SolveContext{pb.lay, pool, *kernels}, pb.ne(), mu, D.data()));
    double worst = 0.0;
    for (i64 j = 0; j < nc; ++j) {
      const double *L = D.data() + j * cnp * cnp;
      for (int a = 0; a < cnp; ++a)
        for (int b = a; b < cnp; ++b) {  // (L L^T)[a][b] against S's upper triangle
          double llt = 0.0;
          for (int c = 0; c <= a; ++c) llt += L[a * cnp + c] * L[b * cnp + c];
          const double want = S[size_t((j * cnp + a) * nS + j * cnp + b)];
          const double scale = std::sqrt(S[size_t((j * cnp + a) * (nS + 1))] * S[size_t((j * cnp + b) * (nS + 1))]);
          worst = std::max(worst, std::fabs(llt - want) / scale);
        }
    }
    EXPECT_LT(worst, 1e-12);
  }
}

// dp^T (J^T J + mu I) dp and dp^T g over the free parameters.
void quadratic_terms(const Problem &pb, const std::vector<double> &dp, double mu, double *dAd, double *gd) {
  const sba::Layout &lay = pb.lay;
  const int cnp = lay.cnp;
  double jd2 = 0.0;
  for (int i = 0; i < lay.n; ++i)
    for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
      const int j = lay.colidx[k];
      const double *A = pb.jac.data() + i64(k) * lay.jblk(), *B = A + 2 * cnp;
      for (int r = 0; r < 2; ++r) {
        double s = 0.0;
        if (lay.cam_free(j))
          for (int a = 0; a < cnp; ++a) s += A[r * cnp + a] * dp[size_t(lay.a_off(j) + a)];
        if (lay.pt_free(i))
          for (int a = 0; a < 3; ++a) s += B[r * 3 + a] * dp[size_t(lay.b_off(i) + a)];
        jd2 += s * s;
      }
    }
  double d2 = 0.0, g = 0.0;
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int a = 0; a < cnp; ++a) {
      const double v = dp[size_t(lay.a_off(j) + a)];
      d2 += v * v;
      g += v * pb.ea[size_t(lay.a_off(j) + a)];
    }
  for (int i = lay.ncon; i < lay.n; ++i)
    for (int a = 0; a < 3; ++a) {
      const double v = dp[size_t(lay.b_off(i) + a)];
      d2 += v * v;
      g += v * pb.eb[size_t(i * 3 + a)];
    }
  *dAd = jd2 + mu * d2;
  *gd = g;
}

// The first solve stops at the loosest forcing term, with a step that is still a descent
// direction whose model reduction is what LM computes for an exact step; with a gradient
// 1e-12 times the first, the forcing term is at its floor and the step the dense Cholesky
// step to 1e-5.
TEST_P(IterativeSchur, StepMatchesCholAsTheGradientFalls) {
  const int cnp = GetParam();
  Problem pb(400, 15, 2, 7, cnp, 21u + unsigned(cnp));
  const double mu = 0.05;
  const sba::Layout &lay = pb.lay;
  sba::ThreadPool pool(2);
  const auto kernels = sba::make_kernels(lay, pool.size());
  const auto solver = sba::make_step_solver(sba::LinSolver::IterativeSchur, sba::SolveContext{lay, pool, *kernels});
  std::vector<double> dp(size_t(lay.nvars()), -1.0);
  ASSERT_EQ(solver->solve(pb.ne(), mu, dp.data()), sba::StepStatus::Solved);
  const std::vector<double> ref = step(pb, sba::LinSolver::Chol, 1, mu);
  for (int q = 0; q < lay.mcon * cnp; ++q) EXPECT_EQ(dp[size_t(q)], 0.0);
  for (int q = 0; q < lay.ncon * 3; ++q) EXPECT_EQ(dp[size_t(lay.b_off(0) + q)], 0.0);
  double dAd = 0.0, gd = 0.0;
  quadratic_terms(pb, dp, mu, &dAd, &gd);
  EXPECT_GT(gd, 0.0);
  EXPECT_NEAR(dAd / gd, 1.0, 1e-9);
  // Loose: not the exact step yet (else this test would not see the forcing term at work).
  double diff = 0.0, norm = 0.0;
  for (size_t q = 0; q < ref.size(); ++q) {
    diff = std::max(diff, std::fabs(dp[q] - ref[q]));
    norm = std::max(norm, std::fabs(ref[q]));
  }
  EXPECT_GT(diff, 1e-6 * norm);

  const double s = 1e-12;
  for (double &v : pb.ea) v *= s;
  for (double &v : pb.eb) v *= s;
  ASSERT_EQ(solver->solve(pb.ne(), mu, dp.data()), sba::StepStatus::Solved);
  diff = 0.0;
  for (size_t q = 0; q < ref.size(); ++q) diff = std::max(diff, std::fabs(dp[q] / s - ref[q]));
  EXPECT_LT(diff, 1e-5 * norm);
}

// The forcing term tightens with the gradient down to a floor of 1e-4: with a gradient 1e-12
// times the first (sqrt: 1e-6), CG stops at the first iterate whose residual is within 1e-4
// of the right-hand side's norm.
TEST_P(IterativeSchur, ForcingTermStopsAtItsFloor) {
  const int cnp = GetParam();
  Problem pb(400, 15, 2, 7, cnp, 23u + unsigned(cnp));
  const double mu = 1e-3;
  const sba::Layout &lay = pb.lay;
  sba::ThreadPool pool(1);
  const auto kernels = sba::make_kernels(lay, pool.size());
  const auto solver = sba::make_step_solver(sba::LinSolver::IterativeSchur, sba::SolveContext{lay, pool, *kernels});
  std::vector<double> dp(size_t(lay.nvars()));
  ASSERT_EQ(solver->solve(pb.ne(), mu, dp.data()), sba::StepStatus::Solved);
  for (double &v : pb.ea) v *= 1e-12;
  for (double &v : pb.eb) v *= 1e-12;
  ASSERT_EQ(solver->solve(pb.ne(), mu, dp.data()), sba::StepStatus::Solved);
  std::vector<double> rhs;
  const std::vector<double> S = assembled_S(pb, pool, *kernels, mu, &rhs);
  const i64 nS = pb.nS();
  const double *da = dp.data() + lay.a_off(lay.mcon);
  double rr = 0.0, bb = 0.0;
  for (i64 r = 0; r < nS; ++r) {
    double v = -rhs[size_t(r)];
    for (i64 c = 0; c < nS; ++c) v += S[size_t(r * nS + c)] * da[c];
    rr += v * v;
    bb += rhs[size_t(r)] * rhs[size_t(r)];
  }
  const double relative = std::sqrt(rr / bb);
  EXPECT_LE(relative, 1e-4);
  EXPECT_GT(relative, 1e-6);
}

TEST_P(IterativeSchur, SameBitsForAnyThreadCount) {
  const Problem pb(700, 20, 1, 3, GetParam(), 31u);
  const std::vector<double> one = step(pb, sba::LinSolver::IterativeSchur, 1, 0.1);
  EXPECT_EQ(one, step(pb, sba::LinSolver::IterativeSchur, 2, 0.1));
  EXPECT_EQ(one, step(pb, sba::LinSolver::IterativeSchur, 3, 0.1));
}

// Blocks stored in single precision are widened before any arithmetic: the step (the point
// passes of every product, the preconditioner) has the bits of the step from double blocks
// holding the same values, and differs from the step of the unrounded blocks.
TEST_P(IterativeSchur, SinglePrecisionBlocksGiveTheBitsOfTheirWidenedValues) {
  const Problem pb(500, 15, 2, 5, GetParam(), 53u);
  const std::vector<float> j32(pb.jac.begin(), pb.jac.end());
  const std::vector<double> widened(j32.begin(), j32.end());
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    sba::ThreadPool pool(threads);
    const auto kernels = sba::make_kernels(pb.lay, pool.size());
    const auto solve = [&](const double *jac, const float *jac32) {
      const auto solver = sba::make_step_solver(sba::LinSolver::IterativeSchur, sba::SolveContext{pb.lay, pool, *kernels});
      std::vector<double> dp(size_t(pb.lay.nvars()), -1.0);
      const sba::NormalEquations ne{jac, pb.U.data(), pb.V.data(), pb.ea.data(), pb.eb.data(), jac32};
      EXPECT_EQ(solver->solve(ne, 0.1, dp.data()), sba::StepStatus::Solved);
      return dp;
    };
    const std::vector<double> single = solve(nullptr, j32.data());
    EXPECT_EQ(single, solve(widened.data(), nullptr));
    EXPECT_NE(single, solve(pb.jac.data(), nullptr));
  }
}

// A NaN in the normal equations, a damped point block that is singular and a reduced system
// that is indefinite are failures (LM then raises the damping), never a crash or a step with
// NaNs. (An indefinite point block is inverted, as sba 1.6 inverts the blocks its retries
// leave: see test_kernels.)
TEST_P(IterativeSchur, RefusesWhatItCannotSolve) {
  const int cnp = GetParam();
  {
    Problem pb(200, 10, 0, 0, cnp, 41u);
    pb.ea[3] = std::nan("");
    bool ok = true;
    step(pb, sba::LinSolver::IterativeSchur, 2, 0.1, &ok);
    EXPECT_FALSE(ok);
  }
  {
    Problem pb(200, 10, 0, 0, cnp, 42u);
    std::fill_n(pb.V.begin() + 50 * 9, 9, 0.0);
    pb.V[size_t(50 * 9)] = -0.1;  // point 50's block, damped by 0.1, has a zero row
    bool ok = true;
    step(pb, sba::LinSolver::IterativeSchur, 2, 0.1, &ok);
    EXPECT_FALSE(ok);
  }
  {
    Problem pb(200, 10, 0, 0, cnp, 43u);
    pb.U[size_t(4 * cnp * cnp)] = -1e6;  // camera 4's block, and with it S, indefinite
    bool ok = true;
    step(pb, sba::LinSolver::IterativeSchur, 1, 0.1, &ok);
    EXPECT_FALSE(ok);
  }
  {  // a zero gradient: the zero step
    Problem pb(200, 10, 0, 0, cnp, 44u);
    std::fill(pb.ea.begin(), pb.ea.end(), 0.0);
    std::fill(pb.eb.begin(), pb.eb.end(), 0.0);
    bool ok = false;
    const std::vector<double> dp = step(pb, sba::LinSolver::IterativeSchur, 1, 0.1, &ok);
    EXPECT_TRUE(ok);
    for (double v : dp) EXPECT_EQ(v, 0.0);
  }
}

// 6: the block sizes compiled specially; 7: the run-time-sized fallback.
INSTANTIATE_TEST_SUITE_P(BlockSizes, IterativeSchur, ::testing::Values(6, 7));

// Cameras with shared parameters (cnp 9: a pose of 6 and a lens of 3, as BAL's). Cameras 0-19
// share their lens in groups of five: each group's lens, with the poses of its cameras, is a
// cluster of the preconditioner (a shared block with own blocks touching nothing else).
// Cameras 20-23 share parameter 6 all four, and 7-8 in pairs: they touch two shared blocks,
// so these blocks and their poses stay alone.
struct SharedProblem {
  Problem pb;
  std::vector<int> group;

  explicit SharedProblem(unsigned seed) : pb(600, 24, 0, 5, 9, seed), group(size_t(24 * 9), -1) {
    for (int j = 0; j < 20; ++j)
      for (int c = 6; c < 9; ++c) group[size_t(j * 9 + c)] = j / 5;
    for (int j = 20; j < 24; ++j) {
      group[size_t(j * 9 + 6)] = 10;
      group[size_t(j * 9 + 7)] = group[size_t(j * 9 + 8)] = 11 + (j - 20) / 2;
    }
    // A lens column close to a pose column in every projection, as a focal length is to the
    // distance along the optical axis: the coupling a preconditioner has to see.
    for (i64 k = 0; k < pb.lay.nvis; ++k)
      for (int r = 0; r < 2; ++r) {
        double *A = pb.jac.data() + k * pb.lay.jblk() + r * 9;
        for (int c = 6; c < 9; ++c) A[c] = 0.02 * A[c] + A[c - 6];
      }
    sba::ThreadPool pool(1);
    sba::make_kernels(pb.lay, 1)->normal_equations(pool, pb.jac.data(), pb.e.data(), pb.U.data(), pb.V.data(),
                                                   pb.ea.data(), pb.eb.data());
    sba::CameraParamOptions o;
    o.param_group = group.data();
    pb.lay.cams = sba::make_camera_map(o, pb.lay);
  }
  const sba::CameraMap &map() const { return pb.lay.cams; }
  // The block holding camera j's parameter c.
  int block_of(int j, int c) const {
    const int u = map().unknown(j, c);
    int b = 0;
    while (map().block_start(b + 1) <= u) ++b;
    return b;
  }
};

// x supported on the blocks `on` (the rest zero), r = S x, z = M^-1 r: on those blocks, z
// against x (the largest difference relative to the largest |x|).
double preconditioned_error(const SharedProblem &sp, int threads, double mu, const std::vector<int> &on) {
  const sba::CameraMap &map = sp.map();
  const i64 nS = sp.pb.lay.camera_unknowns();
  std::vector<double> x(static_cast<size_t>(nS), 0.0), r(static_cast<size_t>(nS)), z(static_cast<size_t>(nS));
  for (int b : on)
    for (i64 u = map.block_start(b); u < map.block_start(b + 1); ++u)
      x[size_t(u)] = std::cos(1.7 * u + 0.3) * std::pow(10.0, double(u % 3) - 1.0);
  sba::ThreadPool pool(threads);
  const auto kernels = sba::make_kernels(sp.pb.lay, pool.size());
  const sba::SolveContext ctx{sp.pb.lay, pool, *kernels};
  EXPECT_TRUE(sba::iterative_schur_product(ctx, sp.pb.ne(), mu, x.data(), r.data()));
  EXPECT_TRUE(sba::iterative_schur_apply_preconditioner(ctx, sp.pb.ne(), mu, r.data(), z.data()));
  double worst = 0.0, scale = 0.0;
  for (int b : on)
    for (i64 u = map.block_start(b); u < map.block_start(b + 1); ++u) {
      worst = std::max(worst, std::fabs(z[size_t(u)] - x[size_t(u)]));
      scale = std::max(scale, std::fabs(x[size_t(u)]));
    }
  return worst / scale;
}

// The preconditioner is S's principal submatrix over each cluster, solved exactly: applied
// to S x for an x on one cluster it gives back x there. So it is over a block that is in no
// cluster. (S's diagonal blocks alone leave the lens-pose coupling out: a relative error of
// order one on a cluster.)
TEST(IterativeSchurShared, PreconditionerSolvesEachClusterExactly) {
  const SharedProblem sp(51u);
  ASSERT_TRUE(sp.map().shared());
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    for (int g = 0; g < 4; ++g) {
      std::vector<int> cluster{sp.block_of(5 * g, 6)};
      for (int j = 5 * g; j < 5 * g + 5; ++j) cluster.push_back(sp.block_of(j, 0));
      EXPECT_LT(preconditioned_error(sp, threads, 0.3, cluster), 1e-8) << "group " << g;
    }
    // Camera 20's pose, and the lens parameter cameras 20-23 share: blocks alone.
    EXPECT_LT(preconditioned_error(sp, threads, 0.3, {sp.block_of(20, 0)}), 1e-10);
    EXPECT_LT(preconditioned_error(sp, threads, 0.3, {sp.block_of(20, 6)}), 1e-10);
    // Camera 20's pose with its lens's other block are no cluster: M leaves out their
    // coupling.
    EXPECT_GT(preconditioned_error(sp, threads, 0.3, {sp.block_of(20, 0), sp.block_of(20, 7)}), 1e-3);
  }
}

// With each lens and its poses in one cluster, CG needs fewer iterations for the same step
// than with S's diagonal blocks alone: a third fewer on this problem at its first solve
// (forcing term 1e-3), 10 against 16.
TEST(IterativeSchurShared, ClustersCutTheConjugateGradients) {
  const SharedProblem sp(52u);
  for (int threads : {1, 2}) {
    sba::ThreadPool pool(threads);
    const auto kernels = sba::make_kernels(sp.pb.lay, pool.size());
    const sba::SolveContext ctx{sp.pb.lay, pool, *kernels};
    std::vector<double> dp(size_t(sp.pb.lay.nvars()));
    const int clustered = sba::iterative_schur_cg_iterations(ctx, sp.pb.ne(), 0.01, dp.data());
    const int blocks = sba::iterative_schur_cg_iterations(ctx, sp.pb.ne(), 0.01, dp.data(), false);
    EXPECT_GE(clustered, 8);
    EXPECT_LE(clustered, 12);
    EXPECT_GE(blocks, 14);
    EXPECT_LE(double(clustered), 0.75 * blocks) << clustered << " against " << blocks;
  }
}

}  // namespace
