// SPDX-License-Identifier: BSD-3-Clause
// Dense S: the reduced camera system assembled into an (m-mcon)cnp square matrix, in the
// storage its factorization asks for, and handed to that factorization (chosen once, by the
// linear solver's kind: src/dense_factorization.h); the points' steps follow by
// back-substitution.
#include <algorithm>
#include <cmath>
#include <vector>

#include "dense_factorization.h"
#include "step_solver.h"
#include "memory.h"

namespace sba {
namespace {

class DenseSchurSolver final : public StepSolver {
 public:
  DenseSchurSolver(std::unique_ptr<DenseFactorization> factorization, const SolveContext &ctx)
      : factorization_(std::move(factorization)), ctx_(ctx),
        nS_(i64(ctx.lay.free_cams()) * ctx.lay.cnp), rhs_(size_t(nS_)) {
    const i64 ld = factorization_->ld();
    resize_prefaulted(S_, size_t(ld * nS_ + 8));
    // S's rows start on cache lines (rows padded to whole lines where the factorization
    // wants that): where the boundary between two threads' block columns falls on a line
    // boundary, no line of S is written by both.
    Sp_ = align_to_line(S_.data());
  }

  StepStatus solve(const NormalEquations &ne, double mu, double *dp) override {
    const Layout &lay = ctx_.lay;
    reduced_.reset();
    // The steps of the fixed cameras and points are 0; the others are all written below.
    std::fill(dp, dp + lay.a_off(lay.mcon), 0.0);
    std::fill(dp + lay.b_off(0), dp + lay.b_off(lay.ncon), 0.0);
    BlockMap map;
    map.base = Sp_;
    map.ld = factorization_->ld();
    map.cnp = lay.cnp;
    // The point blocks' inverses are made where they are used rather than kept: n pnp^2
    // doubles, a sixth of the Jacobian's size on a 2-D problem of tracks of 3.
    if (!ctx_.kernels.assemble(ctx_.pool, ne, nullptr, mu, map, rhs_.data()))
      return StepStatus::SingularPointBlock;
    double *da = dp + lay.a_off(lay.mcon);
    if (!factorization_->solve(Sp_, rhs_.data(), da)) return StepStatus::Failed;
    for (i64 q = 0; q < nS_; ++q)
      if (!std::isfinite(da[q])) return StepStatus::Failed;
    ctx_.kernels.back_substitute(ctx_.pool, ne, nullptr, mu, dp);
    return StepStatus::Solved;
  }

  bool solve_again(const NormalEquations &ne, double mu, double *dp) override {
    const Layout &lay = ctx_.lay;
    if (!reduced_(ne, mu, rhs_.data())) return false;
    std::fill(dp, dp + lay.a_off(lay.mcon), 0.0);
    std::fill(dp + lay.b_off(0), dp + lay.b_off(lay.ncon), 0.0);
    double *da = dp + lay.a_off(lay.mcon);
    if (!factorization_->solve_again(Sp_, rhs_.data(), da)) return false;
    for (i64 q = 0; q < nS_; ++q)
      if (!std::isfinite(da[q])) return false;
    ctx_.kernels.back_substitute(ctx_.pool, ne, reduced_.Vinv(), mu, dp);
    return true;
  }

 private:
  std::unique_ptr<DenseFactorization> factorization_;
  SolveContext ctx_;
  i64 nS_;
  std::vector<double> S_, rhs_;
  double *Sp_ = nullptr;  // S's first entry: S_'s first 64-byte aligned one
  ReducedRhs reduced_{ctx_};  // solve_again's right-hand sides
};

}  // namespace

std::unique_ptr<StepSolver> make_dense_schur_solver(LinSolver kind, const SolveContext &ctx) {
  const i64 nS = i64(ctx.lay.free_cams()) * ctx.lay.cnp;
  std::unique_ptr<DenseFactorization> f = make_dense_factorization(kind, nS, ctx.lay.cnp, ctx.pool);
  if (!f) return nullptr;
  return std::make_unique<DenseSchurSolver>(std::move(f), ctx);
}

}  // namespace sba
