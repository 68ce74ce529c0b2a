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

}  // namespace

bool ReducedRhs::operator()(const NormalEquations &ne, double mu, double *rhs) {
  const Layout &lay = ctx_.lay;
  const int cnp = lay.cnp, pnp = lay.pnp;
  if (!have_vinv_) {
    Vinv_.resize(size_t(lay.n) * size_t(pnp) * size_t(pnp));
    if (!ctx_.kernels.invert_damped_V(ctx_.pool, ne.V, mu, Vinv_.data())) return false;
    have_vinv_ = true;
  }
  const double *Vinv = Vinv_.data();
  if (row_.empty()) by_camera(lay, &row_, &k_);
  y_.resize(size_t(lay.n) * size_t(pnp));
  ctx_.pool.for_range(lay.free_pts(), [&](i64 b, i64 e) {
    for (i64 i = b + lay.ncon; i < e + lay.ncon; ++i) {
      const double *vi = Vinv + i * pnp * pnp, *g = ne.eb + i * pnp;
      for (int a = 0; a < pnp; ++a) {
        double s = 0.0;
        for (int c = 0; c < pnp; ++c) s += vi[a * pnp + c] * g[c];
        y_[size_t(i * pnp + a)] = s;
      }
    }
  });
  ctx_.pool.for_range(lay.free_cams(), [&](i64 b, i64 e) {
    std::vector<double> W(size_t(cnp) * size_t(pnp));
    for (i64 j = b + lay.mcon; j < e + lay.mcon; ++j) {
      double *r = rhs + (j - lay.mcon) * cnp;
      std::copy_n(ne.ea + j * cnp, cnp, r);
      for (int s = lay.colptr[size_t(j)]; s < lay.colptr[size_t(j) + 1]; ++s) {
        const int i = row_[size_t(s)];
        if (i < lay.ncon) continue;
        form_W(lay, ne.jac, k_[size_t(s)], W.data());
        const double *y = y_.data() + i64(i) * pnp;
        for (int a = 0; a < cnp; ++a) {
          double t = 0.0;
          for (int c = 0; c < pnp; ++c) t += W[size_t(a) * pnp + c] * y[c];
          r[a] -= t;
        }
      }
    }
  });
  return true;
}

std::unique_ptr<StepSolver> make_step_solver(LinSolver kind, const SolveContext &ctx) {
  if (ctx.lay.free_cams() == 0 || ctx.lay.free_pts() == 0)
    return std::make_unique<BlockDiagonalSolver>(ctx);
  switch (kind) {
    case LinSolver::LdlAmd:
      return make_ldl_amd_solver(ctx);
    case LinSolver::SparseChol:
      return make_sparse_schur_solver(ctx);
    case LinSolver::IterativeSchur:
      return make_iterative_schur_solver(ctx);
    default:
      return make_dense_schur_solver(kind, ctx);
  }
}

}  // namespace sba
