// SPDX-License-Identifier: BSD-3-Clause
// The LM loop (src/lm_core.cpp) on its own: a fake model and a fake step solver drive it
// through a rejected step and every stop reason, so that what the loop counts, the dampings
// it tries and the reason and iteration count it reports can be stated exactly. The problem
// is one camera of one parameter p seen once: f(p) = p (unless a test says otherwise) against
// the measurement x = 3, from p = 1, so that e = 2, J^T J = 1, J^T e = 2 and the cost is 4.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "kernels.h"
#include "lm.h"
#include "parallel.h"
#include "step_solver.h"
#include "strategy.h"

namespace {

using sba::StepStatus;

constexpr double kX = 3.0, kP0 = 1.0, kCost0 = 4.0;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

sba::Layout one_parameter() {
  sba::Layout lay;
  const char vmask[1] = {1};
  std::string msg;
  EXPECT_TRUE(sba::build_layout(lay, sba::Mode::Mot, 1, 1, 0, 0, 1, 0, 1, vmask, &msg)) << msg;
  return lay;
}

// f and its derivative, with NaN where a test asks for it.
class FakeModel final : public sba::Model {
 public:
  std::function<double(double)> f = [](double p) { return p; };
  std::function<double(double)> df = [](double) { return 1.0; };
  int nan_from_eval = -1;     // evaluations from this one on return NaN (-1: none)
  bool nan_jacobian = false;

  void use_threads(sba::ThreadPool *) override {}
  void eval(double *p, double *hx) override {
    hx[0] = nan_from_eval >= 0 && evals_ >= nan_from_eval ? kNaN : f(p[0]);
    ++evals_;
  }
  bool has_jacobian() const override { return true; }
  void jacobian(double *p, double *jac) override { jac[0] = nan_jacobian ? kNaN : df(p[0]); }
  void fd_jacobian(double *, const double *, double *) override { ADD_FAILURE() << "no differences here"; }

 private:
  int evals_ = 0;
};

// What the fake solver returns at one attempt: a status and a step, or (lm) the damped
// step J^T e / (U + mu) of the blocks it is handed.
struct Move {
  StepStatus status;
  double dp;
  bool lm;
};
Move solved(double dp) { return {StepStatus::Solved, dp, false}; }
Move lm_step() { return {StepStatus::Solved, 0.0, true}; }
Move failed(StepStatus status = StepStatus::Failed) { return {status, 0.0, false}; }

// What the solver was handed at one attempt.
struct Call {
  double mu, U, ea;
};

// Plays the script, then its last move again and again.
class FakeSolver final : public sba::StepSolver {
 public:
  FakeSolver(std::vector<Move> script, std::vector<Call> *calls) : script_(std::move(script)), calls_(calls) {}
  StepStatus solve(const sba::NormalEquations &ne, double mu, double *dp) override {
    calls_->push_back({mu, ne.U[0], ne.ea[0]});
    const Move &m = script_[std::min(calls_->size(), script_.size()) - 1];
    dp[0] = m.lm ? ne.ea[0] / (ne.U[0] + mu) : m.dp;
    return m.status;
  }

 private:
  std::vector<Move> script_;
  std::vector<Call> *calls_;
};

struct Outcome {
  bool ok = false;
  sba::Summary sum;
  double p = kP0;
  std::vector<Call> calls;
  std::vector<std::string> log;
  int progress_calls = 0;
};

struct Case {
  sba::Options opt;
  FakeModel model;
  int stop_at_progress = 0;  // the progress call (1, 2, ...) that asks to stop; 0: none
};

void keep_line(void *ctx, int, const char *line) { static_cast<std::vector<std::string> *>(ctx)->push_back(line); }

Outcome run(Case &s, std::vector<Move> script) {
  Outcome r;
  const sba::Layout lay = one_parameter();
  const double x = kX;
  sba::Options opt = s.opt;
  if (opt.itmax == 0) opt.itmax = 100;
  struct Progress {
    Outcome *r;
    int stop_at;
  } progress{&r, s.stop_at_progress};
  opt.progress = [](void *ctx, const sba_progress *) {
    Progress *pr = static_cast<Progress *>(ctx);
    return ++pr->r->progress_calls == pr->stop_at ? 1 : 0;
  };
  opt.progress_ctx = &progress;
  const sba::Logger log(2, keep_line, &r.log);
  r.ok = sba::solve(lay, s.model, &r.p, &x, nullptr, opt, log, r.sum,
                    [&](std::unique_ptr<sba::StepSolver>) -> std::unique_ptr<sba::StepSolver> {
                      return std::make_unique<FakeSolver>(std::move(script), &r.calls);
                    });
  return r;
}

void expect_counts(const Outcome &r, sba::i64 nfev, sba::i64 njev, sba::i64 nlinsys) {
  EXPECT_EQ(r.sum.nfev, nfev);
  EXPECT_EQ(r.sum.njev, njev);
  EXPECT_EQ(r.sum.nlinsys, nlinsys);
}

int count_lines(const Outcome &r, const std::string &part) {
  int n = 0;
  for (const std::string &line : r.log) n += line.find(part) != std::string::npos;
  return n;
}

// ---- a rejected step, then an accepted one ----

// 1.6's retry: the first step increases the cost and is rejected; mu doubles, and the blocks
// of the next attempt keep the damping the first one added (the strategy's retry hook).
TEST(LmLoop, RejectedStepThenAcceptedOne) {
  Case s;
  s.opt.itmax = 1;
  const Outcome r = run(s, {solved(-1.0), lm_step()});
  ASSERT_TRUE(r.ok);
  ASSERT_EQ(r.calls.size(), 2u);
  EXPECT_EQ(r.calls[0].mu, 1e-3);  // tau * max diag(J^T J)
  EXPECT_EQ(r.calls[0].U, 1.0);
  EXPECT_EQ(r.calls[0].ea, 2.0);
  EXPECT_EQ(r.calls[1].mu, 2e-3);
  EXPECT_EQ(r.calls[1].U, 1.0 + 1e-3);
  EXPECT_EQ(r.p, kP0 + 2.0 / (1.0 + 1e-3 + 2e-3));
  EXPECT_EQ(r.sum.reason, sba::kStopItmax);
  EXPECT_EQ(r.sum.iterations, 1);
  expect_counts(r, 3, 1, 2);  // f at p0 and at both candidates
  EXPECT_EQ(r.progress_calls, 1);
  EXPECT_EQ(r.sum.err0, kCost0);
  EXPECT_LT(r.sum.err, 1e-4);
  EXPECT_EQ(count_lines(r, "SBA: iteration 0: mu"), 2);
}

// A step that is not finite is no step: the damping grows, as for a failed factorization.
TEST(LmLoop, NonFiniteStepIsRetried) {
  Case s;
  s.opt.itmax = 1;
  const Outcome r = run(s, {solved(kNaN), lm_step()});
  ASSERT_TRUE(r.ok);
  ASSERT_EQ(r.calls.size(), 2u);
  EXPECT_EQ(r.calls[1].mu, 2e-3);
  expect_counts(r, 2, 1, 2);
  EXPECT_EQ(count_lines(r, "could not be factored (mu = 0.001)"), 1);
}

// ---- each stop reason on purpose ----

TEST(LmLoopStops, Gradient) {
  Case s;
  s.opt.eps1 = 2.0;  // ||J^T e||_inf = 2
  const Outcome r = run(s, {lm_step()});
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopGradient);
  EXPECT_EQ(r.sum.iterations, 1);
  EXPECT_TRUE(r.calls.empty());
  expect_counts(r, 1, 1, 0);
  EXPECT_EQ(r.p, kP0);
  EXPECT_EQ(r.progress_calls, 1);
}

TEST(LmLoopStops, SmallStep) {
  Case s;
  const Outcome r = run(s, {solved(1e-20)});  // ||dp||^2 = 1e-40 <= eps2^2 ||p||^2 = 1e-24
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopStep);
  EXPECT_EQ(r.sum.iterations, 1);
  expect_counts(r, 1, 1, 1);
  EXPECT_EQ(r.sum.dp2, 1e-20 * 1e-20);
  EXPECT_EQ(r.p, kP0);
}

TEST(LmLoopStops, Itmax) {
  Case s;
  s.opt.itmax = 2;
  const Outcome r = run(s, {lm_step()});
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopItmax);
  EXPECT_EQ(r.sum.iterations, 2);
  expect_counts(r, 3, 2, 2);
  EXPECT_EQ(r.progress_calls, 2);
}

TEST(LmLoopStops, ReductionBelowEps4) {
  Case s;
  s.opt.eps4 = 0.5;
  // ||e|| goes from 2 to 1.9: a relative reduction of 0.05 < eps4.
  const Outcome r = run(s, {solved(0.1)});
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopReduction);
  EXPECT_EQ(r.sum.iterations, 1);
  expect_counts(r, 2, 1, 1);
  EXPECT_EQ(r.p, kP0 + 0.1);  // the step that stops the solve is taken
}

TEST(LmLoopStops, ErrorBelowEps3) {
  Case s;
  s.opt.eps3 = 0.5;
  const Outcome r = run(s, {lm_step()});
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopError);
  EXPECT_EQ(r.sum.iterations, 1);
  expect_counts(r, 2, 1, 1);
  EXPECT_LE(r.sum.err, 0.25);
}

// Every attempt fails: mu is multiplied by 2, 4, 8, ... until nu would overflow 1.6's int
// (2^30 > INT_MAX / 2): 30 attempts. Each counts as a linear system.
TEST(LmLoopStops, Damping) {
  Case s;
  const Outcome r = run(s, {failed()});
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopDamping);
  EXPECT_EQ(r.sum.iterations, 1);
  ASSERT_EQ(r.calls.size(), 30u);
  for (size_t k = 1; k < r.calls.size(); ++k) EXPECT_EQ(r.calls[k].mu, r.calls[k - 1].mu * double(1 << k)) << k;
  expect_counts(r, 1, 1, 30);
  EXPECT_EQ(count_lines(r, "could not be factored"), 30);
  EXPECT_EQ(r.p, kP0);
}

// An attempt that ends at a singular point block is not counted as a linear system (1.6).
TEST(LmLoopStops, DampingAfterSingularPointBlocksCountsNoSystem) {
  Case s;
  const Outcome r = run(s, {failed(StepStatus::SingularPointBlock)});
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopDamping);
  EXPECT_EQ(r.calls.size(), 30u);
  expect_counts(r, 1, 1, 0);
}

TEST(LmLoopStops, NonFiniteAtTheStart) {
  Case s;
  s.model.nan_from_eval = 0;
  const Outcome r = run(s, {lm_step()});
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopNonFinite);
  EXPECT_EQ(r.sum.iterations, 0);
  expect_counts(r, 1, 0, 0);
  EXPECT_EQ(count_lines(r, "returned NaN or Inf at the initial estimate"), 1);
}

TEST(LmLoopStops, NonFiniteJacobian) {
  Case s;
  s.model.nan_jacobian = true;
  const Outcome r = run(s, {lm_step()});
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopNonFinite);
  EXPECT_EQ(r.sum.iterations, 0);
  expect_counts(r, 1, 1, 0);
  EXPECT_EQ(count_lines(r, "the Jacobian has a NaN or Inf entry (or overflows) at iteration 0"), 1);
}

// f is NaN at the candidate: the solve fails where it stood, at p0 and its error.
TEST(LmLoopStops, NonFiniteAtTheCandidate) {
  Case s;
  s.model.nan_from_eval = 1;
  const Outcome r = run(s, {lm_step()});
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopNonFinite);
  EXPECT_EQ(r.sum.iterations, 1);
  expect_counts(r, 2, 1, 1);
  EXPECT_EQ(r.p, kP0);
  EXPECT_EQ(r.sum.err, kCost0);
  EXPECT_EQ(r.progress_calls, 0);
}

TEST(LmLoopStops, Singular) {
  Case s;
  const Outcome r = run(s, {solved(1e13)});  // ||dp||^2 = 1e26 >= (||p||^2 + eps2) / 1e-24
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopSingular);
  EXPECT_EQ(r.sum.iterations, 1);
  expect_counts(r, 1, 1, 1);
  EXPECT_EQ(r.p, kP0);
  EXPECT_EQ(count_lines(r, "almost singular"), 1);
}

TEST(LmLoopStops, User) {
  Case s;
  s.opt.itmax = 10;
  s.stop_at_progress = 2;
  const Outcome r = run(s, {lm_step()});
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopUser);
  EXPECT_EQ(r.sum.iterations, 2);
  expect_counts(r, 3, 2, 2);
}

// A request to stop after the last iteration changes nothing.
TEST(LmLoopStops, UserAfterTheLastIterationKeepsItsReason) {
  Case s;
  s.opt.itmax = 2;
  s.stop_at_progress = 2;
  const Outcome r = run(s, {lm_step()});
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopItmax);
  EXPECT_EQ(r.sum.iterations, 2);
}

// ---- the strategy's half of a step ----

// The predicted reduction dp^T (mu dp + g) is taken in the solver's variables, before the step
// goes back to the units of p. With f(p) = 2p the trust region solves in q = 2p: J^T J = 4
// becomes 1, and J^T e = 6 becomes 3.
TEST(StrategyStep, TrustRegionPredictsInTheSolversVariablesThenScalesTheStep) {
  const sba::Layout lay = one_parameter();
  sba::ThreadPool pool(1);
  const std::unique_ptr<sba::Strategy> tr = sba::make_strategy(sba::StrategyKind::TrustRegion, lay, 0.0);
  const std::unique_ptr<sba::Kernels> kernels = sba::make_kernels(lay, pool.size());
  double jac = 2.0, U = 4.0, ea = 6.0;
  tr->linearized(pool, *kernels, sba::JacobianBlocks{&jac, nullptr}, &U, nullptr, &ea, nullptr);
  EXPECT_EQ(U, 1.0);
  EXPECT_EQ(ea, 3.0);
  double dp = 0.5;
  EXPECT_EQ(tr->step_in_parameters(pool, &ea, nullptr, 0.25, &dp), 0.5 * (0.25 * 0.5 + 3.0));
  EXPECT_EQ(dp, 0.25);
}

// With a solver that damps each parameter (StepSolver::takes_damping) nothing is scaled: the
// solver is handed D = diag(J^T J) = 4 and solves in the units of p, and the same step, 0.25
// here for the 0.5 above, predicts the same reduction.
TEST(StrategyStep, TrustRegionWithADampingSolverStaysInTheUnitsOfP) {
  const sba::Layout lay = one_parameter();
  sba::ThreadPool pool(1);
  const std::unique_ptr<sba::Strategy> tr = sba::make_strategy(sba::StrategyKind::TrustRegion, lay, 0.0, true);
  const std::unique_ptr<sba::Kernels> kernels = sba::make_kernels(lay, pool.size());
  double jac = 2.0, U = 4.0, ea = 6.0;
  tr->linearized(pool, *kernels, sba::JacobianBlocks{&jac, nullptr}, &U, nullptr, &ea, nullptr);
  EXPECT_EQ(jac, 2.0);
  EXPECT_EQ(U, 4.0);
  EXPECT_EQ(ea, 6.0);
  ASSERT_NE(tr->damping(), nullptr);
  EXPECT_EQ(tr->damping()[0], 4.0);
  double dp = 0.25;
  EXPECT_EQ(tr->step_in_parameters(pool, &ea, nullptr, 0.25, &dp), 0.5 * (0.25 * 0.5 + 3.0));
  EXPECT_EQ(dp, 0.25);
}

TEST(StrategyStep, SbaKeepsTheStep) {
  const sba::Layout lay = one_parameter();
  sba::ThreadPool pool(1);
  const std::unique_ptr<sba::Strategy> sba16 = sba::make_strategy(sba::StrategyKind::Sba, lay, 0.0);
  const double ea = 2.0;
  double dp = 0.5;
  EXPECT_EQ(sba16->step_in_parameters(pool, &ea, nullptr, 0.25, &dp), 0.5 * (0.25 * 0.5 + 2.0));
  EXPECT_EQ(dp, 0.5);
}

// The trust region's cost tolerance (eps4) bounds the change of the cost either way: a step
// that raises the cost by no more than eps4 of it is rejected and ends the solve (reason 4, p
// as it was), where damping on would only shrink the step to the same point. One that raises
// it by more is rejected and the solve goes on.
TEST(LmLoopStops, TrustRegionRejectedStepWithinTheCostTolerance) {
  Case s;
  s.opt.strategy = sba::StrategyKind::TrustRegion;
  s.opt.eps4 = 0.1;
  // J^T J = 1: the scaled step is the step. Cost 4 -> 2.05^2 = 4.2025, up by 0.2025 <= 0.4.
  const Outcome r = run(s, {solved(-0.05), lm_step()});
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.sum.reason, sba::kStopReduction);
  EXPECT_EQ(r.sum.iterations, 1);
  ASSERT_EQ(r.calls.size(), 1u);
  expect_counts(r, 2, 1, 1);
  EXPECT_EQ(r.p, kP0);
  EXPECT_EQ(r.sum.err, kCost0);

  // Cost 4 -> 2.5^2 = 6.25, up by 2.25 > 0.4: rejected, and the next attempt is taken.
  Case t;
  t.opt.strategy = sba::StrategyKind::TrustRegion;
  t.opt.eps4 = 0.1;
  t.opt.itmax = 1;
  const Outcome u = run(t, {solved(-0.5), lm_step()});
  ASSERT_TRUE(u.ok);
  EXPECT_EQ(u.sum.reason, sba::kStopItmax);
  ASSERT_EQ(u.calls.size(), 2u);
  EXPECT_GT(u.p, kP0 + 1.0);
}

// sba 1.6's strategy has no such test: the same step is rejected and the damping grows.
TEST(LmLoopStops, SbaDampsOnAfterARejectedStepWithinEps4) {
  Case s;
  s.opt.eps4 = 0.1;
  s.opt.itmax = 1;
  const Outcome r = run(s, {solved(-0.05), lm_step()});
  ASSERT_TRUE(r.ok);
  ASSERT_EQ(r.calls.size(), 2u);
  EXPECT_EQ(r.calls[1].mu, 2e-3);
  EXPECT_GT(r.p, kP0 + 1.0);
}

// The loop with the trust region: the solver sees the scaled system, p moves by the step in
// its own units.
TEST(LmLoop, TrustRegionStepInTheUnitsOfP) {
  Case s;
  s.opt.itmax = 1;
  s.opt.strategy = sba::StrategyKind::TrustRegion;
  s.model.f = [](double p) { return 2.0 * p; };  // e = 1 at p0
  s.model.df = [](double) { return 2.0; };
  const Outcome r = run(s, {solved(0.5)});
  ASSERT_TRUE(r.ok);
  ASSERT_EQ(r.calls.size(), 1u);
  EXPECT_EQ(r.calls[0].U, 1.0);
  EXPECT_EQ(r.calls[0].ea, 1.0);  // J^T e = 2, scaled by 1/2
  EXPECT_EQ(r.p, kP0 + 0.25);
}

}  // namespace
