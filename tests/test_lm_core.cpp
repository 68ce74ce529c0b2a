// SPDX-License-Identifier: BSD-3-Clause
// The LM core (src/lm_core.cpp) and the strategies' retries (src/strategy.cpp), linked from
// the library's objects: the stop-4 test, and the blocks each attempt is handed.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "layout.h"
#include "lm.h"
#include "model.h"
#include "step_solver.h"
#include "strategy.h"
#include "synth.h"

namespace {

using sba::reduction_stalled;

// With eps4 > 0 the expression is the relative RMS reduction test: sqrt(e) - sqrt(en) <
// eps4 sqrt(e). Values chosen so that every operation is exact.
TEST(ReductionStalled, IsTheRelativeRmsTestForPositiveEps4) {
  // sqrt(100) - sqrt(81) = 1 against eps4 * 10.
  EXPECT_TRUE(reduction_stalled(100.0, 81.0, 0.125));
  EXPECT_FALSE(reduction_stalled(100.0, 81.0, 0.0625));
  // The boundary itself: 8 - 7 = 0.125 * 8 is not below it.
  EXPECT_FALSE(reduction_stalled(64.0, 49.0, 0.125));
  EXPECT_FALSE(reduction_stalled(64.0, 49.0, 0.0));
}

// At eps4 = 0 the exact test never fires on a decrease; the expression as sba 1.6 writes it
// does, through the rounding of 2 sqrt(e en), once the relative decrease is tiny.
TEST(ReductionStalled, FiresThroughCancellationAtEps4Zero) {
  const double e = 1294.059147798527;
  EXPECT_TRUE(reduction_stalled(e, 1294.0591476985269, 0.0));   // relative decrease 7.7e-11
  EXPECT_FALSE(reduction_stalled(e, 1294.059147598527, 0.0));   // 1.5e-10
  EXPECT_TRUE(reduction_stalled(3.0, 3.0 * 0.999999999, 0.0));
  EXPECT_FALSE(reduction_stalled(1.0, 0.999999999, 0.0));
  // No decrease at all is not a stall.
  EXPECT_FALSE(reduction_stalled(e, e, 0.0));
}

// Where the cancellation begins: never at a relative decrease of 1e-7 or more, about one step
// in four far below 1e-8. The share is what makes 1.6 end most runs with reason 4.
TEST(ReductionStalled, CancellationLevelIsNearThreeTimesTenToTheMinusEight) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> mag(0.0, 8.0);
  const int kDraws = 4000;
  int fired_big = 0, fired_tiny = 0;
  for (int k = 0; k < kDraws; ++k) {
    const double e = std::pow(10.0, mag(rng));
    fired_big += reduction_stalled(e, e * (1.0 - 1e-7), 0.0);
    fired_big += reduction_stalled(e, e * (1.0 - 1e-3), 0.0);
    fired_tiny += reduction_stalled(e, e * (1.0 - 1e-11), 0.0);
  }
  EXPECT_EQ(fired_big, 0);
  EXPECT_GT(fired_tiny, kDraws / 6);
  EXPECT_LT(fired_tiny, kDraws / 3);
}

// ---------------------------------------------------------------------------------------------
// What a retry damps. The solver is wrapped to keep a copy of the blocks it is handed at every
// attempt; the progress callback numbers the iterations. Each problem is one where sba 1.6
// rejects steps early (the same problems as the drivers' Sba16Retries tests, whose damping
// sequences are 1.6's).

namespace retry {

using sba::i64;

struct Attempt {
  int iteration;
  double mu;
  std::vector<double> U, V;
};

class Recorder final : public sba::StepSolver {
 public:
  Recorder(std::unique_ptr<sba::StepSolver> inner, const sba::Layout &lay, const int *iteration,
           std::vector<Attempt> *out)
      : inner_(std::move(inner)), lay_(lay), iteration_(iteration), out_(out) {}
  sba::StepStatus solve(const sba::NormalEquations &ne, double mu, double *dp) override {
    const size_t nu = size_t(lay_.m) * lay_.cnp * lay_.cnp, nv = size_t(lay_.n) * lay_.pnp * lay_.pnp;
    out_->push_back({*iteration_, mu, std::vector<double>(ne.U, ne.U + nu), std::vector<double>(ne.V, ne.V + nv)});
    return inner_->solve(ne, mu, dp);
  }

 private:
  std::unique_ptr<sba::StepSolver> inner_;
  const sba::Layout &lay_;
  const int *iteration_;
  std::vector<Attempt> *out_;
};

struct Run {
  sba::Layout lay;
  std::vector<Attempt> attempts;
  sba::Summary sum;
};

int count_iteration(void *ctx, const sba_progress *) {
  ++*static_cast<int *>(ctx);
  return 0;
}

// synth problem (20 points, 4 cameras, noise 0.5) perturbed by `perturb` from seed, refined by
// the expert driver of `mode` (the first camera fixed for MotStr) from tau.
Run run(sba::Mode mode, double perturb, unsigned seed, double tau, sba::StrategyKind strategy) {
  synth::Problem pb = synth::make(20, 4, 0.5, perturb, seed);
  pb.fixed_points = pb.truth.data() + pb.m * synth::kCnp;
  pb.fixed_cams = pb.truth.data();
  Run r;
  const int cnp = mode == sba::Mode::Str ? 0 : synth::kCnp, pnp = mode == sba::Mode::Mot ? 0 : synth::kPnp;
  const int mcon = mode == sba::Mode::MotStr ? 1 : 0;
  std::string msg;
  EXPECT_TRUE(sba::build_layout(r.lay, mode, pb.n, pb.m, mcon, 0, cnp, pnp, synth::kMnp, pb.vmask.data(), &msg));
  const sba::ExpertFunc f = mode == sba::Mode::MotStr ? synth::func_motstr
                            : mode == sba::Mode::Mot  ? synth::func_mot
                                                      : synth::func_str;
  const sba::ExpertFunc j = mode == sba::Mode::MotStr ? synth::fjac_motstr
                            : mode == sba::Mode::Mot  ? synth::fjac_mot
                                                      : synth::fjac_str;
  const std::unique_ptr<sba::Model> model = sba::make_expert_model(r.lay, f, j, &pb, false);
  std::vector<double> p = pb.p0;
  double *pp = mode == sba::Mode::Str ? p.data() + pb.m * synth::kCnp : p.data();
  int iteration = 0;
  sba::Options opt;
  opt.tau = tau;
  opt.itmax = 150;
  opt.strategy = strategy;
  opt.progress = count_iteration;
  opt.progress_ctx = &iteration;
  const sba::Logger quiet;
  sba::solve(r.lay, *model, pp, pb.x.data(), nullptr, opt, quiet, r.sum,
             [&](std::unique_ptr<sba::StepSolver> s) -> std::unique_ptr<sba::StepSolver> {
               return std::make_unique<Recorder>(std::move(s), r.lay, &iteration, &r.attempts);
             });
  return r;
}

// (A + mu I)^-1's diagonal for a symmetric 3x3 A (row-major), by cofactors.
std::array<double, 3> inverse_diagonal(const double *a, double mu) {
  const double a00 = a[0] + mu, a11 = a[4] + mu, a22 = a[8] + mu, a01 = a[1], a02 = a[2], a12 = a[5];
  const double c00 = a11 * a22 - a12 * a12, c11 = a00 * a22 - a02 * a02, c22 = a00 * a11 - a01 * a01;
  const double det = a00 * c00 - a01 * (a01 * a22 - a12 * a02) + a02 * (a01 * a12 - a11 * a02);
  return {c00 / det, c11 / det, c22 / det};
}

bool positive_definite3(const double *a) {
  const double det = a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) +
                     a[2] * (a[3] * a[7] - a[4] * a[6]);
  return a[0] > 0 && a[0] * a[4] - a[1] * a[3] > 0 && det > 0;
}

// Calls k - 1 and k of one iteration.
template <class Fn>
int for_each_retry(const Run &r, Fn fn) {
  int retries = 0;
  for (size_t k = 1; k < r.attempts.size(); ++k)
    if (r.attempts[k].iteration == r.attempts[k - 1].iteration) {
      fn(r.attempts[k - 1], r.attempts[k]);
      ++retries;
    }
  return retries;
}

// Off the diagonal, the blocks [first, count) of `now` equal those of `before`.
void expect_blocks(const std::vector<double> &before, const std::vector<double> &now, int d, int first, int count,
                   const char *what) {
  for (int b = first; b < count; ++b)
    for (int r = 0; r < d; ++r)
      for (int c = 0; c < d; ++c)
        if (r != c) ASSERT_EQ(now[size_t(b) * d * d + r * d + c], before[size_t(b) * d * d + r * d + c]) << what << b;
}

}  // namespace retry

// 1.6's motion-and-structure driver: U_j's diagonal accumulates every attempt's mu; V_i's
// diagonal is the diagonal of the previous attempt's (V_i + mu I)^-1, which makes the block
// indefinite (inverted all the same).
TEST(Sba16Retry, MotionAndStructureDampsTheBlocksThePreviousAttemptLeft) {
  const retry::Run r = retry::run(sba::Mode::MotStr, 2.0, 4, 1e-6, sba::StrategyKind::Sba);
  ASSERT_TRUE(r.sum.ok);
  const sba::Layout &lay = r.lay;
  int indefinite = 0;
  const int retries = retry::for_each_retry(r, [&](const retry::Attempt &a, const retry::Attempt &b) {
    retry::expect_blocks(a.U, b.U, 6, lay.mcon, lay.m, "U off the diagonal, camera ");
    retry::expect_blocks(a.V, b.V, 3, 0, lay.n, "V off the diagonal, point ");
    for (int j = lay.mcon; j < lay.m; ++j)
      for (int q = 0; q < 6; ++q) ASSERT_EQ(b.U[size_t(j) * 36 + q * 7], a.U[size_t(j) * 36 + q * 7] + a.mu) << j;
    for (int i = 0; i < lay.n; ++i) {
      const std::array<double, 3> d = retry::inverse_diagonal(a.V.data() + i * 9, a.mu);
      for (int q = 0; q < 3; ++q)
        ASSERT_NEAR(b.V[size_t(i) * 9 + q * 4], d[size_t(q)], 1e-10 * std::fabs(d[size_t(q)])) << i;
      indefinite += !retry::positive_definite3(b.V.data() + i * 9);
    }
  });
  EXPECT_GE(retries, 5);
  EXPECT_GT(indefinite, 0);
  // Every attempt solved its point blocks: each is one linear system.
  EXPECT_EQ(r.sum.nlinsys, sba::i64(r.attempts.size()));
}

// The motion-only and structure-only drivers: the diagonal accumulates the attempts' mu.
TEST(Sba16Retry, MotionOnlyAndStructureOnlyAccumulateTheDamping) {
  for (const sba::Mode mode : {sba::Mode::Mot, sba::Mode::Str}) {
    SCOPED_TRACE(mode == sba::Mode::Mot ? "mot" : "str");
    const bool mot = mode == sba::Mode::Mot;
    const retry::Run r = retry::run(mode, mot ? 10.0 : 6.0, mot ? 4 : 3, 1e-9, sba::StrategyKind::Sba);
    ASSERT_TRUE(r.sum.ok);
    const int d = mot ? 6 : 3, count = mot ? r.lay.m : r.lay.n;
    const int retries = retry::for_each_retry(r, [&](const retry::Attempt &a, const retry::Attempt &b) {
      const std::vector<double> &before = mot ? a.U : a.V, &now = mot ? b.U : b.V;
      retry::expect_blocks(before, now, d, 0, count, "off the diagonal, block ");
      for (int k = 0; k < count; ++k)
        for (int q = 0; q < d; ++q)
          ASSERT_EQ(now[size_t(k) * d * d + q * (d + 1)], before[size_t(k) * d * d + q * (d + 1)] + a.mu) << k;
    });
    EXPECT_GE(retries, mot ? 5 : 3);
  }
}

// sba-clean-retry: every attempt of an iteration gets the undamped blocks, bit for bit.
TEST(Sba16Retry, CleanRetryDampsTheUndampedBlocks) {
  for (const sba::Mode mode : {sba::Mode::MotStr, sba::Mode::Mot, sba::Mode::Str}) {
    const retry::Run r = mode == sba::Mode::MotStr ? retry::run(mode, 2.0, 4, 1e-6, sba::StrategyKind::SbaCleanRetry)
                         : mode == sba::Mode::Mot  ? retry::run(mode, 10.0, 4, 1e-9, sba::StrategyKind::SbaCleanRetry)
                                                   : retry::run(mode, 6.0, 3, 1e-9, sba::StrategyKind::SbaCleanRetry);
    ASSERT_TRUE(r.sum.ok);
    const int retries = retry::for_each_retry(r, [&](const retry::Attempt &a, const retry::Attempt &b) {
      EXPECT_EQ(a.U, b.U);
      EXPECT_EQ(a.V, b.V);
    });
    EXPECT_GE(retries, 2);
  }
}

}  // namespace
