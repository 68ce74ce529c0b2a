// Dense S: the reduced camera system assembled into an (m-mcon)cnp square matrix and
// factored by LAPACK. Cholesky (the default, as in sba 1.6) factors in place; the other
// factorizations are those of the sba_Axb_* helpers (src/dense.h), on the mirrored full
// matrix.
#include <algorithm>
#include <cmath>
#include <vector>

#include "dense.h"
#include "lapack.h"
#include "linsolve.h"
#include "memory.h"
#include "small_dense.h"

namespace sba {
namespace {

// Up to this order, S is factored by the library's own Cholesky (Kernels::cholesky): as fast
// as OpenBLAS's DPOTRF on one thread up to about 2000 unknowns and faster on two
// (block_kernels_benchmark, CholeskyOrder), and its bits do not depend on the thread
// count. Beyond it DPOTRF's packed, cache-blocked kernels win (3000 unknowns: 0.20 s against
// 0.30 s on one thread), and the result depends on the BLAS's own threads. `chol-lapack` is
// DPOTRF/DPOTRS at every size.
constexpr i64 kOwnCholeskyMax = 2048;

// x <- U^-1 y, U row-major upper with row stride ld. The dot products run in eight fixed
// partial sums (the compiler does not reorder a sum itself).
void back_substitute_upper(const double *U, i64 n, i64 ld, const double *y, double *x) {
  for (i64 k = n - 1; k >= 0; --k) {
    const double *u = U + k * ld;
    double acc[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    i64 j = k + 1;
    for (; j + 8 <= n; j += 8)
      for (int q = 0; q < 8; ++q) acc[q] += u[j + q] * x[j + q];
    for (; j < n; ++j) acc[0] += u[j] * x[j];
    double s = 0.0;
    for (double a : acc) s += a;
    x[k] = (y[k] - s) / u[k];
  }
}

class DenseSchurSolver final : public StepSolver {
 public:
  DenseSchurSolver(LinSolver kind, const SolveContext &ctx)
      : kind_(kind), ctx_(ctx), nS_(i64(ctx.lay.free_cams()) * ctx.lay.cnp),
        ld_(kind == LinSolver::Chol || kind == LinSolver::CholLapack ? (nS_ + 8) / 8 * 8 : nS_),
        rhs_(size_t(nS_)), scale_(size_t(nS_)) {
    resize_prefaulted(S_, size_t(ld_ * nS_ + 8));
    // S's rows start on cache lines (for Chol, whose LAPACK calls take a leading
    // dimension, rows padded to 8 doubles): where the boundary between two threads' block
    // columns falls on a line boundary, no line of S is written by both.
    Sp_ = align_to_line(S_.data());
  }

  bool solve(const NormalEquations &ne, double mu, double *dp) override {
    const Layout &lay = ctx_.lay;
    // The steps of the fixed cameras and points are 0; the others are all written below.
    std::fill(dp, dp + lay.a_off(lay.mcon), 0.0);
    std::fill(dp + lay.b_off(0), dp + lay.b_off(lay.ncon), 0.0);
    const i64 nS = nS_, ld = ld_;
    BlockMap map;
    map.base = Sp_;
    map.ld = ld;
    map.cnp = lay.cnp;
    map.zero_dense = true;
    // The point blocks' inverses are made where they are used rather than kept: n pnp^2
    // doubles, a sixth of the Jacobian's size on a 2-D problem of tracks of 3.
    if (!ctx_.kernels.assemble(ctx_.pool, ne, nullptr, mu, map, rhs_.data())) return false;
    double *da = dp + lay.a_off(lay.mcon);
    if (!factor_solve(da)) return false;
    for (i64 q = 0; q < nS; ++q)
      if (!std::isfinite(da[q])) return false;
    ctx_.kernels.back_substitute(ctx_.pool, ne, nullptr, mu, dp);
    return true;
  }

 private:
  // S holds its upper triangle (row-major). Solution into da.
  bool factor_solve(double *da) {
    const int n = int(nS_), ld = int(ld_);
    double *S = Sp_;
    if (kind_ == LinSolver::Chol && nS_ <= kOwnCholeskyMax) {
      // The right-hand side rides along as column nS of S: the factorization leaves
      // U^-T rhs there. The padding after it goes along too, as zero right-hand sides, so
      // that the last columns fill whole vector lanes instead of a scalar loop; it is
      // zeroed every time, since a factorization that failed on a NaN may have left NaNs.
      for (i64 r = 0; r < nS_; ++r) {
        double *row = S + r * ld_;
        row[nS_] = rhs_[size_t(r)];
        std::fill(row + nS_ + 1, row + ld_, 0.0);
      }
      if (!ctx_.kernels.cholesky(ctx_.pool, S, nS_, ld_, ld_ - nS_)) return false;
      for (i64 r = 0; r < nS_; ++r) rhs_[size_t(r)] = S[r * ld_ + nS_];
      back_substitute_upper(S, nS_, ld_, rhs_.data(), da);
      return true;
    }
    const ThreadPool::ForeignThreads lapack(ctx_.pool);  // the BLAS runs its own
    if (kind_ == LinSolver::Chol || kind_ == LinSolver::CholLapack) {
      // Row-major upper is column-major lower: factor in place, no copy.
      int info = 0, one = 1;
      SBA_F77(dpotrf, DPOTRF)("L", &n, S, &ld, &info, 1);
      if (info != 0) return false;
      std::copy(rhs_.begin(), rhs_.end(), da);
      SBA_F77(dpotrs, DPOTRS)("L", &n, &one, S, &ld, da, &n, &info, 1);
      return info == 0;
    }
    // The other factorizations see D S D y = D rhs with D = diag(S)^-1/2, da = D y. Camera
    // parameters of very different units (focal lengths in pixels, rotations in radians)
    // make S badly scaled; Cholesky and LU do not mind, but the normal-equation QR squares
    // the condition number, the SVD cut-off and CG's convergence depend on it.
    std::vector<double> &d = scale_;
    for (int r = 0; r < n; ++r) {
      const double v = S[i64(r) * n + r];
      if (!(v > 0.0)) return false;  // the damped S is positive definite
      d[size_t(r)] = 1.0 / std::sqrt(v);
    }
    for (int r = 0; r < n; ++r)
      for (int c = r; c < n; ++c) {
        const double v = S[i64(r) * n + c] * d[size_t(r)] * d[size_t(c)];
        S[i64(r) * n + c] = S[i64(c) * n + r] = v;
      }
    double *b = rhs_.data();
    for (int r = 0; r < n; ++r) b[r] *= d[size_t(r)];
    bool ok = false;
    switch (kind_) {
      case LinSolver::LDLt:
        ok = dense::solve(dense::Method::LDLt, S, b, da, n);
        break;
      case LinSolver::BK:
        ok = dense::solve(dense::Method::BK, S, b, da, n);
        break;
      case LinSolver::LU:
        ok = dense::solve(dense::Method::LU, S, b, da, n);
        break;
      case LinSolver::QR:
        ok = dense::solve(dense::Method::QR, S, b, da, n);
        break;
      case LinSolver::QRnoQ:
        ok = qr_seminormal(S, b, da, n);
        break;
      case LinSolver::SVD:
        ok = dense::solve(dense::Method::SVD, S, b, da, n);
        break;
      case LinSolver::CG:
        ok = block_jacobi_cg(S, b, da, n);
        break;
      default:
        break;
    }
    for (int r = 0; r < n; ++r) da[r] *= d[size_t(r)];
    return ok;
  }

  // QR without Q: S = QR, so R^T R = S^T S and S x = b becomes R^T R x = S^T b (the
  // semi-normal equations: Q is never formed). That squares S's condition number, which the
  // varying-intrinsics problems cannot afford; corrected semi-normal-equation refinement
  // (x += (R^T R)^-1 S^T (b - S x), while the residual keeps shrinking, at most 10 times)
  // recovers the accuracy of QR itself.
  bool qr_seminormal(const double *S, const double *b, double *x, int n) {
    std::vector<double> &R = qr_;  // S is symmetric: row-major S is column-major S too
    R.assign(S, S + size_t(n) * size_t(n));
    std::vector<double> tau(static_cast<size_t>(n));
    int info = 0, lwork = -1;
    double wq = 0.0;
    SBA_F77(dgeqrf, DGEQRF)(&n, &n, R.data(), &n, tau.data(), &wq, &lwork, &info);
    lwork = std::max(int(wq), n);
    std::vector<double> work(static_cast<size_t>(lwork));
    SBA_F77(dgeqrf, DGEQRF)(&n, &n, R.data(), &n, tau.data(), work.data(), &lwork, &info);
    if (info != 0) return false;
    for (int k = 0; k < n; ++k)
      if (!(R[size_t(k) * n + k] != 0.0)) return false;
    const int one = 1;
    // y = (R^T R)^-1 S^T v, in place in v's copy.
    auto seminormal = [&](const double *v, double *y) {
      for (int a = 0; a < n; ++a) {
        double t = 0.0;
        for (int c = 0; c < n; ++c) t += S[i64(c) * n + a] * v[c];
        y[a] = t;
      }
      int inf = 0;
      SBA_F77(dtrtrs, DTRTRS)("U", "T", "N", &n, &one, R.data(), &n, y, &n, &inf, 1, 1, 1);
      SBA_F77(dtrtrs, DTRTRS)("U", "N", "N", &n, &one, R.data(), &n, y, &n, &inf, 1, 1, 1);
    };
    seminormal(b, x);
    std::vector<double> res(static_cast<size_t>(n)), dx(static_cast<size_t>(n));
    double bn = 0.0;
    for (int a = 0; a < n; ++a) bn += b[a] * b[a];
    auto residual = [&]() {
      double rn = 0.0;
      for (int a = 0; a < n; ++a) {
        double t = b[a];
        for (int c = 0; c < n; ++c) t -= S[i64(a) * n + c] * x[c];
        res[size_t(a)] = t;
        rn += t * t;
      }
      return rn;
    };
    double rn = residual();
    for (int step = 0; step < 10 && rn > 0.0; ++step) {
      seminormal(res.data(), dx.data());
      for (int a = 0; a < n; ++a) x[a] += dx[size_t(a)];
      const double next = residual();
      if (!(next < 0.25 * rn)) {  // no longer converging: rounding level reached, or diverging
        if (!(next <= rn))
          for (int a = 0; a < n; ++a) x[a] -= dx[size_t(a)];
        rn = std::min(rn, next);
        break;
      }
      rn = next;
    }
    // When S is too ill-conditioned for the semi-normal equations even with refinement, the
    // "solution" does not solve S x = b at all; report a failure so that LM damps more.
    if (!(rn <= 1e-12 * bn)) return false;
    for (int a = 0; a < n; ++a)
      if (!std::isfinite(x[a])) return false;
    return true;
  }

  // Conjugate gradients on the scaled S with the camera blocks as preconditioner. As an
  // inexact Newton step it need not converge fully: every CG iterate from 0 lowers the
  // quadratic model, so the LM gain ratio stays meaningful; it stops at a relative residual
  // of 1e-10 or after 2n iterations, and fails only if S shows non-positive curvature.
  bool block_jacobi_cg(const double *S, const double *b, double *x, int n) {
    const int cnp = ctx_.lay.cnp, nb = n / cnp;
    std::vector<double> &M = cg_blocks_;  // Cholesky factors of the diagonal blocks
    M.resize(size_t(nb) * cnp * cnp);
    for (int k = 0; k < nb; ++k) {
      double *blk = M.data() + size_t(k) * cnp * cnp;
      for (int a = 0; a < cnp; ++a)
        for (int c = 0; c < cnp; ++c) blk[a * cnp + c] = S[i64(k * cnp + a) * n + k * cnp + c];
      if (!small::chol(blk, cnp)) return false;
    }
    const size_t nn = static_cast<size_t>(n);
    std::vector<double> r(b, b + n), z(nn), pv(nn), q(nn);
    auto precondition = [&]() {
      z = r;
      for (int k = 0; k < nb; ++k) small::chol_solve(M.data() + size_t(k) * cnp * cnp, z.data() + k * cnp, cnp);
    };
    std::fill(x, x + n, 0.0);
    double bnorm = 0.0;
    for (int q0 = 0; q0 < n; ++q0) bnorm += b[q0] * b[q0];
    bnorm = std::sqrt(bnorm);
    if (bnorm == 0.0) return true;
    precondition();
    pv = z;
    double rz = 0.0;
    for (int q0 = 0; q0 < n; ++q0) rz += r[size_t(q0)] * z[size_t(q0)];
    for (int it = 0; it < 2 * n; ++it) {
      double pq = 0.0;
      for (int a = 0; a < n; ++a) {
        double t = 0.0;
        const double *row = S + i64(a) * n;
        for (int c = 0; c < n; ++c) t += row[c] * pv[size_t(c)];
        q[size_t(a)] = t;
        pq += pv[size_t(a)] * t;
      }
      if (!(pq > 0.0)) return it > 0;  // curvature lost to rounding: keep what we have
      const double alpha = rz / pq;
      double rnorm = 0.0;
      for (int a = 0; a < n; ++a) {
        x[a] += alpha * pv[size_t(a)];
        r[size_t(a)] -= alpha * q[size_t(a)];
        rnorm += r[size_t(a)] * r[size_t(a)];
      }
      if (std::sqrt(rnorm) <= 1e-10 * bnorm) break;
      precondition();
      double rz_new = 0.0;
      for (int a = 0; a < n; ++a) rz_new += r[size_t(a)] * z[size_t(a)];
      const double beta = rz_new / rz;
      rz = rz_new;
      for (int a = 0; a < n; ++a) pv[size_t(a)] = z[size_t(a)] + beta * pv[size_t(a)];
    }
    return true;
  }

  LinSolver kind_;
  SolveContext ctx_;
  i64 nS_;
  i64 ld_;  // S's leading dimension: nS_, or for the Cholesky solvers nS_ + 1 (room for the
            // right-hand side) rounded up to 8
  std::vector<double> S_, rhs_, scale_, cg_blocks_, qr_;
  double *Sp_ = nullptr;  // S's first entry: S_'s first 64-byte aligned one
};

}  // namespace

std::unique_ptr<StepSolver> make_dense_schur_solver(LinSolver kind, const SolveContext &ctx) {
  return std::make_unique<DenseSchurSolver>(kind, ctx);
}

}  // namespace sba
