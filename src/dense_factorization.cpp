// SPDX-License-Identifier: BSD-3-Clause
// The dense factorizations of S: the library's own Cholesky, LAPACK's, and the methods of the
// sba_Axb_* helpers (src/dense.h) on a diagonally scaled copy.
#include "dense_factorization.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "lapack.h"
#include "small_dense.h"

namespace sba {
namespace {

// Up to this order, S is factored by the library's own Cholesky: as fast as OpenBLAS's DPOTRF
// on one thread up to about this size and faster on two (block_kernels_benchmark,
// CholeskyOrder), and its bits do not depend on the thread count. Beyond it DPOTRF's packed,
// cache-blocked kernels win, and the result depends on the BLAS's own threads.
constexpr i64 kOwnCholeskyMax = 2048;

// Both Cholesky factorizations pad S's rows to whole cache lines (8 doubles) with room for
// one more column: the own Cholesky carries the right-hand side there, and where the boundary
// between two threads' block columns falls on a line boundary, no line of S is written by
// both.
i64 padded_ld(i64 n) { return (n + 8) / 8 * 8; }

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

// The library's own Cholesky (the default). The right-hand side rides along as column n of
// S: the factorization leaves U^-T rhs there.
class OwnCholesky final : public DenseFactorization {
 public:
  OwnCholesky(i64 n, ThreadPool &pool)
      : DenseFactorization(n, padded_ld(n)), pool_(pool), factor_(own_dense_cholesky()) {}

  bool solve(double *S, double *rhs, double *x) override {
    const i64 n = n_, ld = ld_;
    // The padding after the right-hand side goes along too, as zero right-hand sides, so that
    // the last columns fill whole vector lanes instead of a scalar loop; it is zeroed every
    // time, since a factorization that failed on a NaN may have left NaNs.
    for (i64 r = 0; r < n; ++r) {
      double *row = S + r * ld;
      row[n] = rhs[r];
      std::fill(row + n + 1, row + ld, 0.0);
    }
    if (!factor_(pool_, S, n, ld, ld - n)) return false;
    for (i64 r = 0; r < n; ++r) rhs[r] = S[r * ld + n];
    back_substitute_upper(S, n, ld, rhs, x);
    return true;
  }

 private:
  ThreadPool &pool_;
  DenseCholesky factor_;
};

// LAPACK's DPOTRF/DPOTRS, whose blocking (and so bits) follow the BLAS's threads.
class LapackCholesky final : public DenseFactorization {
 public:
  LapackCholesky(i64 n, ThreadPool &pool) : DenseFactorization(n, padded_ld(n)), pool_(pool) {}

  bool solve(double *S, double *rhs, double *x) override {
    const int n = int(n_), ld = int(ld_), one = 1;
    int info = 0;
    const ThreadPool::ForeignThreads lapack(pool_);  // the BLAS runs its own
    // Row-major upper is column-major lower: factor in place, no copy.
    SBA_F77(dpotrf, DPOTRF)("L", &n, S, &ld, &info, 1);
    if (info != 0) return false;
    std::copy(rhs, rhs + n_, x);
    SBA_F77(dpotrs, DPOTRS)("L", &n, &one, S, &ld, x, &n, &info, 1);
    return info == 0;
  }

 private:
  ThreadPool &pool_;
};

// The other factorizations see D S D y = D rhs with D = diag(S)^-1/2, x = D y. Camera
// parameters of very different units (focal lengths in pixels, rotations in radians) make S
// badly scaled; Cholesky and LU do not mind, but the normal-equation QR squares the condition
// number, the SVD cut-off and CG's convergence depend on it. S is stored unpadded (ld = n)
// and mirrored to a full matrix, as the sba_Axb_* methods read it.
class Equilibrated : public DenseFactorization {
 public:
  bool solve(double *S, double *rhs, double *x) final {
    const i64 n = n_;
    std::vector<double> &d = scale_;
    for (i64 r = 0; r < n; ++r) {
      const double v = S[r * n + r];
      if (!(v > 0.0)) return false;  // the damped S is positive definite
      d[size_t(r)] = 1.0 / std::sqrt(v);
    }
    for (i64 r = 0; r < n; ++r)
      for (i64 c = r; c < n; ++c) {
        const double v = S[r * n + c] * d[size_t(r)] * d[size_t(c)];
        S[r * n + c] = S[c * n + r] = v;
      }
    for (i64 r = 0; r < n; ++r) rhs[r] *= d[size_t(r)];
    const ThreadPool::ForeignThreads lapack(pool_);  // LAPACK's BLAS runs its own threads
    const bool ok = solve_scaled(S, rhs, x, int(n));
    for (i64 r = 0; r < n; ++r) x[r] *= d[size_t(r)];
    return ok;
  }

 protected:
  Equilibrated(i64 n, ThreadPool &pool) : DenseFactorization(n, n), pool_(pool), scale_(size_t(n)) {}
  // x = S^-1 b for the scaled, full S.
  virtual bool solve_scaled(const double *S, const double *b, double *x, int n) = 0;

 private:
  ThreadPool &pool_;
  std::vector<double> scale_;
};

// A method of the sba_Axb_* helpers.
class AxbMethod final : public Equilibrated {
 public:
  AxbMethod(i64 n, ThreadPool &pool, dense::Method method)
      : Equilibrated(n, pool), solve_(dense::solver(method)) {}

 private:
  bool solve_scaled(const double *S, const double *b, double *x, int n) override {
    return solve_(S, b, x, n);
  }
  dense::Solve solve_;
};

// The SVD's pseudo-solve sums over singular vectors that rounding spreads over every
// unknown. An unknown that S leaves on its own (its row zero but for the diagonal: a camera
// that sees no point, where only the damping sits) would then get a step of rounding size,
// where the other factorizations keep it apart and give it b_r / S_rr, zero when its
// right-hand side is. Such an unknown is solved alone and the SVD sees the others; an S
// without one goes to the SVD as it is.
class DecoupledSvd final : public Equilibrated {
 public:
  DecoupledSvd(i64 n, ThreadPool &pool) : Equilibrated(n, pool), svd_(dense::solver(dense::Method::SVD)) {}

 private:
  bool solve_scaled(const double *S, const double *b, double *x, int n) override {
    coupled_.clear();
    for (int r = 0; r < n; ++r) {
      const double *row = S + i64(r) * n;
      bool alone = true;
      for (int c = 0; c < n && alone; ++c) alone = c == r || row[c] == 0.0;
      if (alone)
        x[r] = b[r] / row[r];
      else
        coupled_.push_back(r);
    }
    const int k = int(coupled_.size());
    if (k == n) return svd_(S, b, x, n);
    if (k == 0) return true;
    A_.resize(size_t(k) * size_t(k));
    bk_.resize(size_t(k));
    xk_.resize(size_t(k));
    for (int a = 0; a < k; ++a) {
      const double *row = S + i64(coupled_[size_t(a)]) * n;
      for (int c = 0; c < k; ++c) A_[size_t(a) * size_t(k) + size_t(c)] = row[coupled_[size_t(c)]];
      bk_[size_t(a)] = b[coupled_[size_t(a)]];
    }
    if (!svd_(A_.data(), bk_.data(), xk_.data(), k)) return false;
    for (int a = 0; a < k; ++a) x[coupled_[size_t(a)]] = xk_[size_t(a)];
    return true;
  }

  dense::Solve svd_;
  std::vector<int> coupled_;
  std::vector<double> A_, bk_, xk_;
};

// z = M^-1 r with M the camera blocks of S (block Jacobi), by their Cholesky factors.
class CameraBlocks final : public dense::Preconditioner {
 public:
  CameraBlocks(const double *S, int n, int cnp, std::vector<double> &factors) : cnp_(cnp), M_(factors) {
    const int nb = n / cnp;
    M_.resize(size_t(nb) * cnp * cnp);
    for (int k = 0; k < nb && ok_; ++k) {
      double *blk = M_.data() + size_t(k) * cnp * cnp;
      for (int a = 0; a < cnp; ++a)
        for (int c = 0; c < cnp; ++c) blk[a * cnp + c] = S[i64(k * cnp + a) * n + k * cnp + c];
      ok_ = small::chol(blk, cnp);
    }
  }
  bool ok() const { return ok_; }
  void apply(const std::vector<double> &r, std::vector<double> &z) const override {
    z = r;
    const int nb = int(r.size()) / cnp_;
    for (int k = 0; k < nb; ++k)
      small::chol_solve(M_.data() + size_t(k) * cnp_ * cnp_, z.data() + size_t(k) * cnp_, cnp_);
  }

 private:
  int cnp_;
  std::vector<double> &M_;
  bool ok_ = true;
};

// Conjugate gradients with the camera blocks as preconditioner, as an inexact Newton step
// (dense::truncated_cg): it stops at a relative residual of 1e-10 or after 2n iterations.
class BlockJacobiCg final : public Equilibrated {
 public:
  BlockJacobiCg(i64 n, int cnp, ThreadPool &pool) : Equilibrated(n, pool), cnp_(cnp) {}

 private:
  bool solve_scaled(const double *S, const double *b, double *x, int n) override {
    const CameraBlocks M(S, n, cnp_, blocks_);
    return M.ok() && dense::truncated_cg(S, b, x, n, 2 * n, 1e-10, M);
  }
  int cnp_;
  std::vector<double> blocks_;
};

}  // namespace

std::unique_ptr<DenseFactorization> make_cholesky(i64 n, ThreadPool &pool) {
  if (n <= kOwnCholeskyMax) return std::make_unique<OwnCholesky>(n, pool);
  return std::make_unique<LapackCholesky>(n, pool);
}

std::unique_ptr<DenseFactorization> make_lapack_cholesky(i64 n, ThreadPool &pool) {
  return std::make_unique<LapackCholesky>(n, pool);
}

std::unique_ptr<DenseFactorization> make_axb_factorization(dense::Method method, i64 n, ThreadPool &pool) {
  return std::make_unique<AxbMethod>(n, pool, method);
}

std::unique_ptr<DenseFactorization> make_svd(i64 n, ThreadPool &pool) {
  return std::make_unique<DecoupledSvd>(n, pool);
}

std::unique_ptr<DenseFactorization> make_block_jacobi_cg(i64 n, int cnp, ThreadPool &pool) {
  return std::make_unique<BlockJacobiCg>(n, cnp, pool);
}

}  // namespace sba
