// SPDX-License-Identifier: BSD-3-Clause
#include "step_solver.h"

#include <algorithm>
#include <cmath>

#include "small_dense.h"

namespace sba {

namespace {

// No free points or no free cameras: (J^T J + mu I) is block diagonal, one small Cholesky
// per free camera or point (the 1.6 motion-only and structure-only drivers).
class BlockDiagonalSolver final : public StepSolver {
 public:
  explicit BlockDiagonalSolver(const SolveContext &ctx) : lay_(ctx.lay), pool_(ctx.pool) {
    const size_t d = size_t(std::max(lay_.cnp, lay_.pnp));
    blk_.resize(size_t(pool_.size()) * d * d);
  }

  StepStatus solve(const NormalEquations &ne, double mu, double *dp) override {
    const Layout &lay = lay_;
    std::fill(dp, dp + lay.nvars(), 0.0);
    if (lay.cnp > 0 && !all_blocks(lay.m - lay.mcon, [&](i64 q, double *scratch) {
          const i64 j = q + lay.mcon;
          return one(ne.U + j * lay.cnp * lay.cnp, ne.ea + j * lay.cnp, lay.cnp, mu,
                     dp + lay.a_off(int(j)), scratch);
        }))
      return StepStatus::Failed;
    if (lay.pnp > 0 && !all_blocks(lay.n - lay.ncon, [&](i64 q, double *scratch) {
          const i64 i = q + lay.ncon;
          return one(ne.V + i * lay.pnp * lay.pnp, ne.eb + i * lay.pnp, lay.pnp, mu,
                     dp + lay.b_off(int(i)), scratch);
        }))
      return StepStatus::Failed;
    return StepStatus::Solved;
  }

 private:
  // fn(q, scratch) for q in [0, count) over the threads; false if any is.
  template <class Fn>
  bool all_blocks(i64 count, Fn fn) {
    const size_t d = size_t(std::max(lay_.cnp, lay_.pnp));
    return pool_.all_ranges(count, [&](int t, i64 b, i64 e) {
      for (i64 q = b; q < e; ++q)
        if (!fn(q, blk_.data() + size_t(t) * d * d)) return false;
      return true;
    });
  }

  static bool one(const double *M, const double *g, int d, double mu, double *x, double *b) {
    if (d <= 0) return true;  // never: cnp, pnp > 0 here; tells the optimizer so
    std::copy_n(M, size_t(d) * size_t(d), b);
    for (int a = 0; a < d; ++a) b[a * d + a] += mu;
    if (!small::chol(b, d)) return false;
    std::copy_n(g, size_t(d), x);
    small::chol_solve(b, x, d);
    for (int a = 0; a < d; ++a)
      if (!std::isfinite(x[a])) return false;
    return true;
  }

  const Layout &lay_;
  ThreadPool &pool_;
  std::vector<double> blk_;  // one d x d block per thread
};

// Held camera parameters (camera_map.h) get the step -0.0, the identity of addition, so that
// p + dp leaves their bits as they are (-0.0 included). In the PerCamera shape their columns
// are zero, so the solvers find a step of 0 for their pinned rows of S; in the Blocks shape
// they are no rows of S, and the map's expansion gives them -0.0 already.
class PinHeld final : public StepSolver {
 public:
  PinHeld(std::unique_ptr<StepSolver> inner, const Layout &lay) : inner_(std::move(inner)), lay_(lay) {}
  StepStatus solve(const NormalEquations &ne, double mu, double *dp) override {
    const StepStatus st = inner_->solve(ne, mu, dp);
    lay_.cams.pin_held(dp);
    return st;
  }
  bool takes_damping() const override { return inner_->takes_damping(); }

 private:
  std::unique_ptr<StepSolver> inner_;
  const Layout &lay_;
};

std::unique_ptr<StepSolver> pinned(std::unique_ptr<StepSolver> s, const Layout &lay) {
  if (!s || !lay.cams.any_held()) return s;
  return std::make_unique<PinHeld>(std::move(s), lay);
}

}  // namespace

bool block_diagonal(const Layout &lay) {
  return lay.free_cams() == 0 || (lay.free_pts() == 0 && lay.cams.per_camera());
}

std::unique_ptr<StepSolver> make_step_solver(LinSolver kind, const SolveContext &ctx) {
  const Layout &lay = ctx.lay;
  if (kind == LinSolver::BlockDiagonal || block_diagonal(lay)) return pinned(std::make_unique<BlockDiagonalSolver>(ctx), lay);
  switch (kind) {
    case LinSolver::LdlAmd:
      return pinned(make_ldl_amd_solver(ctx), lay);
    case LinSolver::SparseChol:
      return pinned(make_sparse_schur_solver(ctx), lay);
    case LinSolver::IterativeSchur:
      return pinned(make_iterative_schur_solver(ctx), lay);
    default:
      return pinned(make_dense_schur_solver(kind, ctx), lay);
  }
}

}  // namespace sba
