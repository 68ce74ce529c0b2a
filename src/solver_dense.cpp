// Dense S: the reduced camera system assembled into an (m-mcon)cnp square matrix and
// factored by LAPACK. Cholesky (the default, as in sba 1.6) factors in place; the other
// factorizations go through the sba_Axb_* helpers on the mirrored full matrix.
#include <algorithm>
#include <cmath>
#include <vector>

#include "lapack.h"
#include "linsolve.h"

namespace sba {
namespace {

class DenseSchurSolver final : public StepSolver {
 public:
  DenseSchurSolver(LinSolver kind, const SolveContext &ctx)
      : kind_(kind), ctx_(ctx), nS_(i64(ctx.lay.free_cams()) * ctx.lay.cnp),
        Vinv_(size_t(i64(ctx.lay.n) * ctx.lay.pnp * ctx.lay.pnp)), S_(size_t(nS_ * nS_)),
        rhs_(size_t(nS_)) {}

  bool solve(const NormalEquations &ne, double mu, double *dp) override {
    const Layout &lay = ctx_.lay;
    std::fill(dp, dp + lay.nvars(), 0.0);
    if (!ctx_.kernels.invert_damped_V(ctx_.pool, ne.V, mu, Vinv_.data())) return false;
    const i64 nS = nS_;
    ctx_.pool.for_range(nS, [&](i64 b, i64 e) {
      std::fill(S_.begin() + b * nS, S_.begin() + e * nS, 0.0);
    });
    BlockMap map;
    map.base = S_.data();
    map.ld = nS;
    map.cnp = lay.cnp;
    ctx_.kernels.assemble(ctx_.pool, ne, Vinv_.data(), mu, map, rhs_.data());
    double *da = dp + lay.a_off(lay.mcon);
    if (!factor_solve(da)) return false;
    for (i64 q = 0; q < nS; ++q)
      if (!std::isfinite(da[q])) return false;
    ctx_.kernels.back_substitute(ctx_.pool, ne, Vinv_.data(), dp);
    return true;
  }

 private:
  // S holds its upper triangle (row-major). Solution into da.
  bool factor_solve(double *da) {
    const int n = int(nS_);
    double *S = S_.data();
    if (kind_ == LinSolver::Chol) {
      // Row-major upper is column-major lower: factor in place, no copy.
      int info = 0, one = 1;
      SBA_F77(dpotrf, DPOTRF)("L", &n, S, &n, &info, 1);
      if (info != 0) return false;
      std::copy(rhs_.begin(), rhs_.end(), da);
      SBA_F77(dpotrs, DPOTRS)("L", &n, &one, S, &n, da, &n, &info, 1);
      return info == 0;
    }
    for (int r = 0; r < n; ++r)
      for (int c = r + 1; c < n; ++c) S[i64(c) * n + r] = S[i64(r) * n + c];
    double *b = rhs_.data();
    switch (kind_) {
      case LinSolver::LDLt:
        return sba_Axb_LDLt(S, b, da, n, 0) == 1;
      case LinSolver::BK:
        return sba_Axb_BK(S, b, da, n, 0) == 1;
      case LinSolver::LU:
        return sba_Axb_LU(S, b, da, n, 0) == 1;
      case LinSolver::QR:
        return sba_Axb_QR(S, b, da, n, 0) == 1;
      case LinSolver::QRnoQ:
        return sba_Axb_QRnoQ(S, b, da, n, 0) == 1;
      case LinSolver::SVD:
        return sba_Axb_SVD(S, b, da, n, 0) == 1;
      case LinSolver::CG:
        // Converged to well below the accuracy that the LM gain ratio can tell apart;
        // 2n iterations leave room for rounding on ill-conditioned S.
        return sba_Axb_CG(S, b, da, n, 10 * n, 1e-9, SBA_CG_JACOBI, 0) > 0;
      default:
        return false;
    }
  }

  LinSolver kind_;
  SolveContext ctx_;
  i64 nS_;
  std::vector<double> Vinv_, S_, rhs_;
};

}  // namespace

std::unique_ptr<StepSolver> make_dense_schur_solver(LinSolver kind, const SolveContext &ctx) {
  return std::make_unique<DenseSchurSolver>(kind, ctx);
}

}  // namespace sba
