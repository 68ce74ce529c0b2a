// SPDX-License-Identifier: BSD-3-Clause
// Dense S: the reduced camera system assembled into an (m-mcon)cnp square matrix, in the
// storage its factorization asks for, and handed to that factorization (chosen once, by the
// linear solver's kind: src/dense_factorization.h); the points' steps follow by
// back-substitution.
#include <algorithm>
#include <cmath>
#include <vector>

#include "dense_factorization.h"
#include "mapped_schur.h"
#include "memory.h"
#include "step_solver.h"
#include "unknowns.h"

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

 private:
  std::unique_ptr<DenseFactorization> factorization_;
  SolveContext ctx_;
  i64 nS_;
  std::vector<double> S_, rhs_;
  double *Sp_ = nullptr;  // S's first entry: S_'s first 64-byte aligned one
};

// The same over shared unknowns (mapped_schur.h): S of the unknowns' order, made by the
// mapped assembly from every point's (V_i + mu I)^-1, and the cameras' steps the unknowns'.
class MappedDenseSchurSolver final : public StepSolver {
 public:
  MappedDenseSchurSolver(std::unique_ptr<DenseFactorization> factorization, const SolveContext &ctx)
      : factorization_(std::move(factorization)), ctx_(ctx), schur_(ctx.lay, ctx.pool.size()),
        nS_(ctx.lay.camera_unknowns()), rhs_(size_t(nS_)), du_(size_t(nS_)) {
    const i64 ld = factorization_->ld();
    resize_prefaulted(S_, size_t(ld * nS_ + 8));
    Sp_ = align_to_line(S_.data());
    Vinv_.resize(size_t(ctx.lay.n) * size_t(ctx.lay.pnp) * size_t(ctx.lay.pnp));
  }

  StepStatus solve(const NormalEquations &ne, double mu, double *dp) override {
    const Layout &lay = ctx_.lay;
    std::fill(dp, dp + lay.nvars(), 0.0);
    if (lay.free_pts() > 0 && !ctx_.kernels.invert_damped_V(ctx_.pool, ne.V, mu, Vinv_.data()))
      return StepStatus::SingularPointBlock;
    UnknownBlocks map;
    map.base = Sp_;
    map.ld = factorization_->ld();
    map.start = lay.cams.block_start.data();
    schur_.assemble(ctx_.pool, ne, Vinv_.data(), mu, map, rhs_.data());
    if (!factorization_->solve(Sp_, rhs_.data(), du_.data())) return StepStatus::Failed;
    for (i64 q = 0; q < nS_; ++q)
      if (!std::isfinite(du_[size_t(q)])) return StepStatus::Failed;
    to_cameras(lay, du_.data(), -0.0, dp);
    if (lay.free_pts() > 0) ctx_.kernels.back_substitute(ctx_.pool, ne, Vinv_.data(), mu, dp);
    return StepStatus::Solved;
  }

 private:
  std::unique_ptr<DenseFactorization> factorization_;
  SolveContext ctx_;
  MappedSchur schur_;
  i64 nS_;
  std::vector<double> S_, rhs_, du_, Vinv_;
  double *Sp_ = nullptr;
};

}  // namespace

std::unique_ptr<DenseFactorization> make_dense_factorization(LinSolver kind, i64 n, int cnp, ThreadPool &pool) {
  switch (kind) {
    case LinSolver::Chol: return make_cholesky(n, pool);
    case LinSolver::CholLapack: return make_lapack_cholesky(n, pool);
    case LinSolver::LDLt: return make_axb_factorization(dense::Method::LDLt, n, pool);
    case LinSolver::BK: return make_axb_factorization(dense::Method::BK, n, pool);
    case LinSolver::LU: return make_axb_factorization(dense::Method::LU, n, pool);
    case LinSolver::QR: return make_axb_factorization(dense::Method::QR, n, pool);
    case LinSolver::QRnoQ: return make_axb_factorization(dense::Method::RefinedQRnoQ, n, pool);
    case LinSolver::SVD: return make_svd(n, pool);
    case LinSolver::CG: return make_block_jacobi_cg(n, cnp, pool);
    default: return nullptr;
  }
}

std::unique_ptr<StepSolver> make_dense_schur_solver(LinSolver kind, const SolveContext &ctx) {
  const Layout &lay = ctx.lay;
  // Block Jacobi (CG's preconditioner) over the cameras' blocks; over shared unknowns, whose
  // blocks differ in size, Jacobi.
  const int block = lay.cams.shared() ? 1 : lay.cnp;
  std::unique_ptr<DenseFactorization> f = make_dense_factorization(kind, lay.camera_unknowns(), block, ctx.pool);
  if (!f) return nullptr;
  if (lay.cams.shared()) return std::make_unique<MappedDenseSchurSolver>(std::move(f), ctx);
  return std::make_unique<DenseSchurSolver>(std::move(f), ctx);
}

}  // namespace sba
