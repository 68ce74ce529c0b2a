// SPDX-License-Identifier: BSD-3-Clause
// The LM strategies (sba_ext_options.strategy, SBA_STRATEGY; src/strategy.cpp): "sba" is the
// default and 1.6's algorithm; "trust-region" reaches the same minima in fewer iterations with
// every linear solver, driver, loss and weighting, and keeps the library's guarantees (same
// bits for any thread count, clean stops). Linked from the library's objects, so that the
// retries can be watched (the blocks each attempt is handed) and the "sba" strategies' stop-4
// test called on its own.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "layout.h"
#include "lm.h"
#include "model.h"
#include "sba_ext.h"
#include "step_solver.h"
#include "strategy.h"
#include "synth.h"

namespace {

using synth::kCnp;
using synth::kMnp;
using synth::kPnp;

struct Outcome {
  int ret = 0;
  double info[SBA_INFOSZ] = {};
  std::vector<double> p;
};

struct SolveSetup {
  const char *strategy = nullptr;
  const char *solver = nullptr;
  const char *loss = nullptr;
  int nthreads = 0;
  int mcon = 0, ncon = 0;
  const double *opts = nullptr;
  const std::vector<double> *covx = nullptr;
  int (*progress)(void *, const sba_progress *) = nullptr;
  void *progress_ctx = nullptr;
};

Outcome motstr(synth::Problem &pb, const SolveSetup &s) {
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.strategy = s.strategy;
  ext.linsolver = s.solver;
  ext.loss = s.loss;
  ext.nthreads = s.nthreads;
  ext.progress = s.progress;
  ext.progress_ctx = s.progress_ctx;
  ext.quiet = 1;
  Outcome o;
  o.p = pb.p0;
  double *covx = s.covx ? const_cast<double *>(s.covx->data()) : nullptr;
  o.ret = sba_motstr_levmar_x_ext(pb.n, s.ncon, pb.m, s.mcon, pb.vmask.data(), o.p.data(), kCnp, kPnp,
                                  pb.x.data(), covx, kMnp, synth::func_motstr, synth::fjac_motstr, &pb,
                                  200, 0, s.opts, o.info, &ext);
  return o;
}

Outcome with(synth::Problem &pb, const char *strategy, const char *solver = nullptr) {
  SolveSetup s;
  s.strategy = strategy;
  s.solver = solver;
  return motstr(pb, s);
}

std::vector<std::string> words(const char *list) {
  std::istringstream in(list);
  std::vector<std::string> out;
  for (std::string w; in >> w;) out.push_back(w);
  return out;
}

TEST(Strategy, NamesAndValidity) {
  EXPECT_STREQ(sba_strategy_names(), "sba sba-clean-retry trust-region");
  EXPECT_EQ(sba_strategy_valid("sba-clean-retry"), 1);
  EXPECT_EQ(sba_strategy_valid("sba"), 1);
  EXPECT_EQ(sba_strategy_valid("trust-region"), 1);
  EXPECT_EQ(sba_strategy_valid("trust_region"), 0);
  EXPECT_EQ(sba_strategy_valid(""), 0);
  EXPECT_EQ(sba_strategy_valid(nullptr), 0);
}

TEST(Strategy, UnknownNameIsABadArgument) {
  synth::Problem pb = synth::make(40, 4, 0.1, 0.05, 71);
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.strategy = "levenberg";
  std::vector<double> p = pb.p0;
  double info[SBA_INFOSZ];
  testing::internal::CaptureStderr();
  const int ret = sba_motstr_levmar_x_ext(pb.n, 0, pb.m, 0, pb.vmask.data(), p.data(), kCnp, kPnp,
                                          pb.x.data(), nullptr, kMnp, synth::func_motstr,
                                          synth::fjac_motstr, &pb, 100, 0, nullptr, info, &ext);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(ret, SBA_ERROR);
  EXPECT_EQ(info[6], SBA_STOP_NONE);
  EXPECT_NE(err.find("unknown strategy \"levenberg\" (known: sba sba-clean-retry trust-region)"), std::string::npos)
      << err;
  EXPECT_EQ(p, pb.p0);
}

// "sba" named is the default, bit for bit; the trust region is a different algorithm.
TEST(Strategy, SbaByNameIsTheDefault) {
  synth::Problem pb = synth::make(120, 7, 0.5, 0.05, 72);
  const Outcome def = with(pb, nullptr), sba = with(pb, "sba"), tr = with(pb, "trust-region");
  ASSERT_GT(def.ret, 0);
  EXPECT_EQ(sba.p, def.p);
  for (int q = 0; q < SBA_INFOSZ; ++q) EXPECT_EQ(sba.info[q], def.info[q]) << q;
  EXPECT_NE(tr.p, def.p);
}

// The legacy entry points read SBA_STRATEGY; an unknown name falls back to sba with a warning.
TEST(Strategy, EnvironmentVariableSwitchesTheLegacyEntryPoints) {
  synth::Problem pb = synth::make(100, 6, 0.4, 0.05, 73);
  const Outcome sba = with(pb, "sba"), tr = with(pb, "trust-region");
  auto legacy = [&](std::string *err) {
    Outcome o;
    o.p = pb.p0;
    testing::internal::CaptureStderr();
    o.ret = sba_motstr_levmar_x(pb.n, 0, pb.m, 0, pb.vmask.data(), o.p.data(), kCnp, kPnp, pb.x.data(),
                                nullptr, kMnp, synth::func_motstr, synth::fjac_motstr, &pb, 200, 0,
                                nullptr, o.info);
    *err = testing::internal::GetCapturedStderr();
    return o;
  };
  std::string err;
  ASSERT_EQ(setenv("SBA_STRATEGY", "trust-region", 1), 0);
  const Outcome env_tr = legacy(&err);
  EXPECT_EQ(env_tr.p, tr.p);
  EXPECT_EQ(env_tr.info[5], tr.info[5]);
  EXPECT_EQ(err, "");
  ASSERT_EQ(setenv("SBA_STRATEGY", "fast", 1), 0);
  const Outcome env_bad = legacy(&err);
  unsetenv("SBA_STRATEGY");
  EXPECT_EQ(env_bad.p, sba.p);
  EXPECT_NE(err.find("unknown SBA_STRATEGY \"fast\" (known: sba sba-clean-retry trust-region); using sba"),
            std::string::npos)
      << err;
}

// Every linear solver (the list the library reports, so new ones are covered) reaches sba's
// minimum through the trust region, in fewer iterations, with and without fixed blocks.
TEST(Strategy, TrustRegionReachesSbasMinimumWithEverySolver) {
  synth::Problem pb = synth::make(150, 8, 0.5, 0.05, 74);
  synth::Problem fixed = synth::make(120, 7, 0.3, 0.05, 75);
  for (const std::string &solver : words(sba_linsolver_names())) {
    SCOPED_TRACE(solver);
    const Outcome ref = with(pb, "sba", solver.c_str()), tr = with(pb, "trust-region", solver.c_str());
    ASSERT_GT(ref.ret, 0);
    ASSERT_GT(tr.ret, 0);
    EXPECT_NEAR(tr.info[1] / ref.info[1], 1.0, 2e-6);
    EXPECT_EQ(tr.info[6], 4);  // the relative cost tolerance
    EXPECT_LT(tr.info[5], ref.info[5]);
    SolveSetup s;
    s.solver = solver.c_str();
    s.mcon = 2;
    s.ncon = 5;
    s.strategy = "sba";
    const Outcome fref = motstr(fixed, s);
    s.strategy = "trust-region";
    const Outcome ftr = motstr(fixed, s);
    ASSERT_GT(ftr.ret, 0);
    EXPECT_NEAR(ftr.info[1] / fref.info[1], 1.0, 2e-6);
    for (int q = 0; q < 2 * kCnp; ++q) EXPECT_EQ(ftr.p[q], fixed.p0[q]);
    for (int q = 0; q < 5 * kPnp; ++q)
      EXPECT_EQ(ftr.p[fixed.m * kCnp + q], fixed.p0[fixed.m * kCnp + q]);
  }
}

TEST(Strategy, TrustRegionResultsDoNotDependOnTheThreadCount) {
  synth::Problem pb = synth::make(160, 9, 0.5, 0.05, 76);
  SolveSetup s;
  s.strategy = "trust-region";
  s.mcon = 1;
  s.ncon = 3;
  s.nthreads = 1;
  const Outcome one = motstr(pb, s);
  ASSERT_GT(one.ret, 0);
  for (int threads : {2, 3, 5}) {
    s.nthreads = threads;
    const Outcome o = motstr(pb, s);
    EXPECT_EQ(o.p, one.p) << threads << " threads";
    for (int q = 0; q < SBA_INFOSZ; ++q) EXPECT_EQ(o.info[q], one.info[q]) << q;
  }
}

// sba 1.6's retries (the default) and the clean ones, on a problem where a step is rejected at
// the third iteration: the same bits for any thread count with the solvers that run on threads,
// and the same minimum. 1.6's retry of that step fails to factor until the damping dominates
// (about 1e5, from 3.2); the clean retry succeeds at twice the damping.
TEST(Strategy, RetriesGiveTheSameBitsForAnyThreadCount) {
  synth::Problem pb = synth::make(400, 10, 0.5, 2.0, 3);
  const double opts[SBA_OPTSSZ] = {1e-6, 1e-12, 1e-12, 1e-12, 0.0};
  for (const char *strategy : {"sba", "sba-clean-retry"})
    for (const char *solver : {"chol", "sparse-chol", "ldl-amd", "iterative-schur", "cg"}) {
      SCOPED_TRACE(std::string(strategy) + " " + solver);
      SolveSetup s;
      s.strategy = strategy;
      s.solver = solver;
      s.opts = opts;
      s.mcon = 1;
      s.nthreads = 1;
      const Outcome one = motstr(pb, s);
      ASSERT_GT(one.ret, 0);
      EXPECT_GT(one.info[9], one.info[5]) << "no step was retried";
      EXPECT_NEAR(one.info[1] / one.info[0], 5.41293e-6, 1e-11);
      for (int threads : {2, 3}) {
        s.nthreads = threads;
        const Outcome o = motstr(pb, s);
        EXPECT_EQ(o.p, one.p) << threads << " threads";
        for (int q = 0; q < SBA_INFOSZ; ++q) EXPECT_EQ(o.info[q], one.info[q]) << q;
      }
    }
}

// With a robust loss and with measurement covariances the trust region minimizes the same
// cost as sba's LM and gets to the same value.
TEST(Strategy, TrustRegionWithALossAndWithCovariances) {
  synth::Problem pb = synth::make(150, 8, 0.5, 0.05, 77);
  for (int k = 0; k < 12; ++k) pb.x[size_t(k) * 17] += 40.0;  // outliers
  SolveSetup s;
  s.loss = "huber";
  s.strategy = "sba";
  const Outcome ref = motstr(pb, s);
  s.strategy = "trust-region";
  const Outcome tr = motstr(pb, s);
  ASSERT_GT(ref.ret, 0);
  ASSERT_GT(tr.ret, 0);
  EXPECT_NEAR(tr.info[1] / ref.info[1], 1.0, 2e-6);
  EXPECT_LT(tr.info[5], ref.info[5]);

  synth::Problem pw = synth::make(150, 8, 0.5, 0.05, 78);
  std::vector<double> covx(size_t(pw.nvis) * 4);
  for (int k = 0; k < pw.nvis; ++k) {
    const double a = 0.5 + (k % 5) * 0.3, c = 0.1 * ((k % 3) - 1);
    covx[size_t(k) * 4 + 0] = a;
    covx[size_t(k) * 4 + 1] = covx[size_t(k) * 4 + 2] = c;
    covx[size_t(k) * 4 + 3] = 2.0 - 0.2 * (k % 4);
  }
  SolveSetup w;
  w.covx = &covx;
  w.strategy = "sba";
  const Outcome wref = motstr(pw, w);
  w.strategy = "trust-region";
  const Outcome wtr = motstr(pw, w);
  ASSERT_GT(wref.ret, 0);
  ASSERT_GT(wtr.ret, 0);
  EXPECT_NEAR(wtr.info[1] / wref.info[1], 1.0, 2e-6);
}

// The motion-only and structure-only drivers (block-diagonal systems) take the strategy too.
TEST(Strategy, TrustRegionInTheMotionAndStructureDrivers) {
  synth::Problem pb = synth::make(120, 7, 0.5, 0.05, 79);
  auto mot = [&](const char *strategy) {
    sba_ext_options ext;
    sba_ext_options_init(&ext);
    ext.strategy = strategy;
    Outcome o;
    o.p.assign(pb.p0.begin(), pb.p0.begin() + pb.m * kCnp);
    pb.fixed_points = pb.truth.data() + pb.m * kCnp;
    o.ret = sba_mot_levmar_x_ext(pb.n, pb.m, 0, pb.vmask.data(), o.p.data(), kCnp, pb.x.data(), nullptr,
                                 kMnp, synth::func_mot, synth::fjac_mot, &pb, 100, 0, nullptr, o.info,
                                 &ext);
    return o;
  };
  auto str = [&](const char *strategy) {
    sba_ext_options ext;
    sba_ext_options_init(&ext);
    ext.strategy = strategy;
    Outcome o;
    o.p.assign(pb.p0.begin() + pb.m * kCnp, pb.p0.end());
    pb.fixed_cams = pb.truth.data();
    o.ret = sba_str_levmar_x_ext(pb.n, 0, pb.m, pb.vmask.data(), o.p.data(), kPnp, pb.x.data(), nullptr,
                                 kMnp, synth::func_str, synth::fjac_str, &pb, 100, 0, nullptr, o.info,
                                 &ext);
    return o;
  };
  const Outcome mref = mot("sba"), mtr = mot("trust-region");
  const Outcome sref = str("sba"), str_tr = str("trust-region");
  ASSERT_GT(mref.ret, 0);
  ASSERT_GT(mtr.ret, 0);
  ASSERT_GT(sref.ret, 0);
  ASSERT_GT(str_tr.ret, 0);
  EXPECT_NEAR(mtr.info[1] / mref.info[1], 1.0, 2e-6);
  EXPECT_NEAR(str_tr.info[1] / sref.info[1], 1.0, 2e-6);
  EXPECT_LE(mtr.info[5], mref.info[5]);
  EXPECT_LE(str_tr.info[5], sref.info[5]);
}

struct Trace {
  std::vector<double> errors;
  int stop_at = 0;
};

int record(void *ctx, const sba_progress *state) {
  Trace &t = *static_cast<Trace *>(ctx);
  t.errors.push_back(state->error);
  return t.stop_at > 0 && state->iteration >= t.stop_at;
}

// eps4 is the trust region's relative cost tolerance: the solve ends at the first accepted
// step that lowers the cost by no more than eps4 of it, and not before.
TEST(Strategy, TrustRegionStopsAtTheRelativeCostTolerance) {
  synth::Problem pb = synth::make(150, 8, 0.5, 0.05, 80);
  for (double eps4 : {1e-2, 1e-4}) {
    SCOPED_TRACE(eps4);
    const double opts[SBA_OPTSSZ] = {SBA_INIT_MU, 1e-15, 1e-15, 1e-15, eps4};
    Trace trace;
    SolveSetup s;
    s.strategy = "trust-region";
    s.opts = opts;
    s.progress = record;
    s.progress_ctx = &trace;
    const Outcome o = motstr(pb, s);
    ASSERT_GT(o.ret, 1);
    EXPECT_EQ(o.info[6], 4);
    ASSERT_EQ(trace.errors.size(), size_t(o.ret));
    std::vector<double> e = {o.info[0]};
    e.insert(e.end(), trace.errors.begin(), trace.errors.end());
    const size_t last = e.size() - 1;
    EXPECT_LE(e[last - 1] - e[last], eps4 * e[last - 1]);
    for (size_t k = 1; k < last; ++k)
      if (e[k] < e[k - 1]) EXPECT_GT(e[k - 1] - e[k], eps4 * e[k - 1]) << k;
  }
}

// The progress callback sees every trust-region iteration and can stop it (reason 9, p the
// last accepted estimate).
TEST(Strategy, TrustRegionProgressAndUserStop) {
  synth::Problem pb = synth::make(150, 8, 0.5, 0.05, 81);
  Trace all, stopped;
  stopped.stop_at = 2;
  SolveSetup s;
  s.strategy = "trust-region";
  s.progress = record;
  s.progress_ctx = &all;
  const Outcome full = motstr(pb, s);
  s.progress_ctx = &stopped;
  const Outcome o = motstr(pb, s);
  ASSERT_GT(full.ret, 2);
  EXPECT_EQ(all.errors.size(), size_t(full.ret));
  EXPECT_EQ(o.ret, 2);
  EXPECT_EQ(o.info[6], SBA_STOP_USER);
  EXPECT_EQ(o.info[1], all.errors[1]);
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

// Hands each solve to the solver it wraps, and says that it takes a damping per parameter only
// when `pass` is set; records whether it was handed one.
class DampingPassed final : public sba::StepSolver {
 public:
  DampingPassed(std::unique_ptr<sba::StepSolver> inner, bool pass, bool *handed)
      : inner_(std::move(inner)), pass_(pass), handed_(handed) {}
  sba::StepStatus solve(const sba::NormalEquations &ne, double mu, double *dp) override {
    if (ne.damping) *handed_ = true;
    return inner_->solve(ne, mu, dp);
  }
  bool takes_damping() const override { return pass_ && inner_->takes_damping(); }

 private:
  std::unique_ptr<sba::StepSolver> inner_;
  bool pass_;
  bool *handed_;
};

struct TrustRegionRun {
  sba::Summary sum;
  std::vector<double> p;
  bool handed = false;
};

// The trust region on a synth problem (first camera and three points fixed) through `kind`,
// the solver's damping per parameter used or not.
TrustRegionRun trust_region(sba::LinSolver kind, bool pass) {
  synth::Problem pb = synth::make(150, 8, 0.5, 0.05, 77);
  pb.fixed_points = pb.truth.data() + pb.m * synth::kCnp;
  pb.fixed_cams = pb.truth.data();
  sba::Layout lay;
  std::string msg;
  EXPECT_TRUE(sba::build_layout(lay, sba::Mode::MotStr, pb.n, pb.m, 1, 3, synth::kCnp, synth::kPnp, synth::kMnp,
                                pb.vmask.data(), &msg));
  const std::unique_ptr<sba::Model> model =
      sba::make_expert_model(lay, synth::func_motstr, synth::fjac_motstr, &pb, false);
  TrustRegionRun r;
  r.p = pb.p0;
  sba::Options opt;
  opt.itmax = 100;
  opt.strategy = sba::StrategyKind::TrustRegion;
  opt.solver = kind;
  const sba::Logger quiet;
  EXPECT_TRUE(sba::solve(lay, *model, r.p.data(), pb.x.data(), nullptr, opt, quiet, r.sum,
                         [&](std::unique_ptr<sba::StepSolver> s) -> std::unique_ptr<sba::StepSolver> {
                           return std::make_unique<DampingPassed>(std::move(s), pass, &r.handed);
                         }));
  return r;
}

}  // namespace

// Marquardt's damping mu diag(J^T J) taken as it stands by the solvers that can (the Schur
// solvers over per-camera blocks) is the scaled system the others solve: the same steps to
// rounding, so the same iterations, evaluations and minimum.
TEST(Strategy, TrustRegionDampingPerParameterIsTheScaledSystem) {
  for (sba::LinSolver kind : {sba::LinSolver::Chol, sba::LinSolver::LU, sba::LinSolver::SparseChol}) {
    SCOPED_TRACE(int(kind));
    const TrustRegionRun damped = trust_region(kind, true), scaled = trust_region(kind, false);
    EXPECT_TRUE(damped.handed);
    EXPECT_FALSE(scaled.handed);
    EXPECT_EQ(damped.sum.reason, sba::kStopReduction);
    EXPECT_EQ(damped.sum.reason, scaled.sum.reason);
    EXPECT_EQ(damped.sum.iterations, scaled.sum.iterations);
    EXPECT_EQ(damped.sum.nfev, scaled.sum.nfev);
    EXPECT_EQ(damped.sum.nlinsys, scaled.sum.nlinsys);
    EXPECT_NEAR(damped.sum.err / scaled.sum.err, 1.0, 1e-12);
    for (size_t q = 0; q < damped.p.size(); ++q)
      EXPECT_NEAR(damped.p[q], scaled.p[q], 1e-9 * std::max(1.0, std::fabs(scaled.p[q]))) << q;
  }
}

namespace {

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
      EXPECT_GE(b.mu, 2.0 * a.mu);  // mu *= nu, nu >= 2
    });
    EXPECT_GE(retries, 2);
  }
}

// ---------------------------------------------------------------------------------------------
// sba 1.6's stop-4 test (reduction_stalled), the "sba" strategies' convergence test.

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

}  // namespace
