// SPDX-License-Identifier: BSD-3-Clause
// Dense S: the reduced camera system assembled into a square matrix of its order (the free
// cameras' parameters, or the unknowns where they are shared: schur_assembly.h), in the
// storage its factorization asks for, and handed to that factorization (chosen once, by the
// linear solver's kind: src/dense_factorization.h); the points' steps follow by
// back-substitution.
#include <algorithm>
#include <cmath>
#include <vector>

#include "dense_factorization.h"
#include "memory.h"
#include "schur_assembly.h"
#include "step_solver.h"

namespace sba {
namespace {

class DenseSchurSolver final : public StepSolver {
 public:
  DenseSchurSolver(std::unique_ptr<DenseFactorization> factorization, const SolveContext &ctx)
      : factorization_(std::move(factorization)), ctx_(ctx), assembly_(ctx),
        nS_(ctx.lay.camera_unknowns()), rhs_(size_t(nS_)) {
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
    BlockMap cams;
    cams.base = Sp_;
    cams.ld = factorization_->ld();
    cams.cnp = lay.cnp;
    UnknownBlocks unknowns;
    unknowns.base = Sp_;
    unknowns.ld = factorization_->ld();
    unknowns.start = lay.cams.block_starts();
    if (!assembly_.assemble(ne, mu, cams, unknowns, rhs_.data())) return StepStatus::SingularPointBlock;
    double *da = assembly_.solution(dp);
    if (!factorization_->solve(Sp_, rhs_.data(), da)) return StepStatus::Failed;
    for (i64 q = 0; q < nS_; ++q)
      if (!std::isfinite(da[q])) return StepStatus::Failed;
    assembly_.finish(ne, mu, dp);
    return StepStatus::Solved;
  }
  // The per-camera assembly damps as the kernels do; the map of shared unknowns adds mu alone.
  bool takes_damping() const override { return ctx_.lay.cams.per_camera(); }

 private:
  std::unique_ptr<DenseFactorization> factorization_;
  SolveContext ctx_;
  SchurAssembly assembly_;
  i64 nS_;
  std::vector<double> S_, rhs_;
  double *Sp_ = nullptr;  // S's first entry: S_'s first 64-byte aligned one
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
  const int block = lay.cams.per_camera() ? lay.cnp : 1;
  std::unique_ptr<DenseFactorization> f = make_dense_factorization(kind, lay.camera_unknowns(), block, ctx.pool);
  if (!f) return nullptr;
  return std::make_unique<DenseSchurSolver>(std::move(f), ctx);
}

}  // namespace sba
