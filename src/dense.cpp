// SPDX-License-Identifier: BSD-3-Clause
// Dense linear algebra behind sba.h: the sba_Axb_* solvers, the symmetric inverses and
// sba_mat_cholinv (exported by c_api_dense.cpp), and the library's own use of them (dense.h).
//
// Conventions shared by every entry point:
//  - A == NULL is a no-op returning 1: sba 1.6 callers used such a call to release the
//    static buffers of its wrappers. There is nothing to release here (every buffer is a
//    per-call std::vector, so concurrent calls never share state), but the call stays legal.
//  - m <= 0, a NULL B or x (or output matrix), or a NaN/Inf anywhere in the inputs the
//    function reads: 0.
//  - The caller's A and B are never written, except that the symmetric inverses return
//    their result in A. Results go to x (or A/B for the inverses) only on success, so x may
//    alias B, and a failed call leaves every output untouched. (For sba_Axb_CG, running out
//    of iterations is a success: x gets the last iterate; see conjugate_gradients.)
//  - Reference LAPACK's XERBLA stops the process, so arguments are validated here and
//    workspace sizes never go below the documented minima; LAPACK must never see a bad one.
//
// Numerically singular input is reported as failure (0) even when LAPACK finds no exactly
// zero pivot, because rounding usually turns an exact zero into a tiny number and the
// resulting "solution" is noise. The tests, with eps = DBL_EPSILON and m the order, are:
//  - QR, LU (upper triangular factor T):  |t_ii| <= m*eps*max_{k<=i} |t_ki|.
//    Scaling a column of A scales the matching column of T, so the test does not depend
//    on column scaling; for QR, max_k |r_ki| is within sqrt(m) of ||A(:,i)||_2, so the test
//    says that column i is, to rounding, in the span of the columns before it.
//  - QRnoQ: |r_ii| <= sqrt(m*eps)*max(max_{k<=i} |r_ki|, max_j |r_jj|). It solves the
//    normal equations A^T A x = A^T b with A^T A = R^T R, whose error bound is
//    cond(A)^2 * eps. The column part is the Cholesky test below applied to A^T A
//    (r_ii^2 against (A^T A)_ii = ||A(:,i)||^2); the global part uses
//    cond_2(A) = cond_2(R) >= max|r_jj| / min|r_ii|. Either way it fails when the normal
//    equations provably carry no digits instead of returning noise; the price is that a
//    badly scaled but otherwise benign A may be refused, for which QR is the better choice.
//  - Cholesky (A = R^T R):  r_ii^2 <= m*eps*a_ii. r_ii^2 is what is left of a_ii after
//    eliminating the earlier rows, so this flags cancellation down to rounding level and is
//    invariant under symmetric diagonal scaling D A D.
//  - LDL^T: |d_i| <= m*eps*(|a_ii| + sum_k l_ik^2 |d_k|), the same cancellation test written
//    for the indefinite case (d_i = a_ii - sum_k l_ik^2 d_k).
//  - Bunch-Kaufman: a 1x1 pivot d, or the smaller eigenvalue magnitude of a 2x2 pivot block,
//    <= m*eps*(largest |a_ij| in the original row(s) the pivot came from).
//  - SVD does not fail on singular A: singular values <= m*eps*s_max are treated as zero and
//    the minimum-norm least-squares solution (pseudo-inverse times B) is returned. It fails
//    only if DGESDD fails or s_max is zero (A == 0).
// Any non-finite solution is a failure as well.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

#include "dense.h"
#include "finite.h"
#include "lapack.h"
#include "sba_export.h"

namespace sba::dense {
namespace {

using Vec = std::vector<double>;
using IVec = std::vector<int>;

constexpr double kEps = std::numeric_limits<double>::epsilon();
// CG tolerance when the caller passes eps <= 0: close to what double precision can
// resolve on a well-conditioned system, without asking for the impossible.
constexpr double kDefaultCgEps = 1e-12;

// Reads the caller's matrix as the logical A(i, j) in either storage order, so the
// algorithms are written once.
struct View {
  const double *a;
  int m;
  std::size_t rs, cs;
  View(const double *p, int n, bool colmaj)
      : a(p), m(n), rs(colmaj ? 1 : std::size_t(n)), cs(colmaj ? std::size_t(n) : 1) {}
  double operator()(int i, int j) const { return a[std::size_t(i) * rs + std::size_t(j) * cs]; }
};

std::size_t idx(int i, int j, int m) { return std::size_t(i) + std::size_t(j) * std::size_t(m); }

Vec to_colmajor(const View &A) {
  const int m = A.m;
  Vec c(std::size_t(m) * std::size_t(m));
  for (int j = 0; j < m; ++j)
    for (int i = 0; i < m; ++i) c[idx(i, j, m)] = A(i, j);
  return c;
}

using sba::all_finite;
bool all_finite(const Vec &v) { return all_finite(v.data(), std::int64_t(v.size())); }

double dot(const Vec &u, const Vec &v) {
  double s = 0.0;
  for (std::size_t k = 0; k < u.size(); ++k) s += u[k] * v[k];
  return s;
}

// Euclidean norm with scaling so that entries near the overflow or underflow limits do not
// make a convergence test lie.
double norm2(const Vec &v) {
  double scale = 0.0;
  for (double e : v) scale = std::max(scale, std::fabs(e));
  if (scale == 0.0 || !std::isfinite(scale)) return scale;
  double s = 0.0;
  for (double e : v) {
    const double t = e / scale;
    s += t * t;
  }
  return scale * std::sqrt(s);
}

// LAPACK reports the optimal workspace as a double. Never go below the documented minimum
// (some LAPACK versions under-report), and refuse sizes an int cannot hold.
bool workspace_size(double queried, long long minimum, int &lwork) {
  double w = std::isfinite(queried) ? std::ceil(queried) : 0.0;
  w = std::max(w, double(minimum));
  w = std::max(w, 1.0);
  if (w > double(std::numeric_limits<int>::max())) return false;
  lwork = int(w);
  return true;
}

// ---- factorizations with their failure tests (see the file comment) ----

// With also_global, each |t_ii| must in addition exceed tol * max_j |t_jj|.
bool triangular_diag_ok(const Vec &t, int m, double tol, bool also_global) {
  double diagmax = 0.0;
  if (also_global)
    for (int j = 0; j < m; ++j) diagmax = std::max(diagmax, std::fabs(t[idx(j, j, m)]));
  for (int i = 0; i < m; ++i) {
    double ref = diagmax;
    for (int k = 0; k <= i; ++k) ref = std::max(ref, std::fabs(t[idx(k, i, m)]));
    if (!(std::fabs(t[idx(i, i, m)]) > tol * ref)) return false;
  }
  return true;
}

bool qr_factor(Vec &a, Vec &tau, int m, double tol, bool also_global) {
  int info = 0, lwork = -1;
  double wq = 0.0;
  SBA_F77(dgeqrf, DGEQRF)(&m, &m, a.data(), &m, tau.data(), &wq, &lwork, &info);
  if (info != 0 || !workspace_size(wq, m, lwork)) return false;
  Vec work(std::size_t(lwork), 0.0);
  SBA_F77(dgeqrf, DGEQRF)(&m, &m, a.data(), &m, tau.data(), work.data(), &lwork, &info);
  return info == 0 && triangular_diag_ok(a, m, tol, also_global);
}

// Solves T y = rhs (or T^T y = rhs) in place for the upper triangular T in t.
bool upper_solve(const Vec &t, Vec &rhs, int m, bool transpose) {
  const char uplo = 'U', trans = transpose ? 'T' : 'N', diag = 'N';
  const int nrhs = 1;
  int info = 0;
  SBA_F77(dtrtrs, DTRTRS)(&uplo, &trans, &diag, &m, &nrhs, t.data(), &m, rhs.data(), &m, &info,
                          1, 1, 1);
  return info == 0;
}

// A = R^T R in the upper triangle of c; diag holds the a_ii of the matrix before factoring.
bool cholesky_upper(Vec &c, int m, const Vec &diag) {
  const char uplo = 'U';
  int info = 0;
  SBA_F77(dpotrf, DPOTRF)(&uplo, &m, c.data(), &m, &info, 1);
  if (info != 0) return false;
  const double tol = double(m) * kEps;
  for (int i = 0; i < m; ++i) {
    const double r = c[idx(i, i, m)];
    if (!(r * r > tol * diag[i])) return false;
  }
  return true;
}

Vec diagonal(const Vec &c, int m) {
  Vec d(std::size_t(m), 0.0);
  for (int i = 0; i < m; ++i) d[i] = c[idx(i, i, m)];
  return d;
}

bool lu_factor(Vec &a, IVec &ipiv, int m) {
  int info = 0;
  SBA_F77(dgetrf, DGETRF)(&m, &m, a.data(), &m, ipiv.data(), &info);
  return info == 0 && triangular_diag_ok(a, m, double(m) * kEps, false);
}

// DSYTRF with uplo 'U' works from the last row up. At step k, ipiv[k] > 0 means a 1x1 pivot
// after swapping rows/columns k and ipiv[k]-1; ipiv[k] == ipiv[k-1] < 0 means a 2x2 pivot
// block on k-1, k after swapping k-1 and -ipiv[k]-1, its off-diagonal above the diagonal.
// Replaying the swaps tells which original row each pivot came from, so that a pivot is
// judged against the largest entry of its own row: a global reference would reject
// well-posed but badly scaled matrices, which the normal equations of bundle adjustment
// often are.
bool bk_factor(Vec &a, IVec &ipiv, int m) {
  Vec rowmax(std::size_t(m), 0.0);
  for (int j = 0; j < m; ++j)
    for (int i = 0; i <= j; ++i) {
      const double e = std::fabs(a[idx(i, j, m)]);
      rowmax[i] = std::max(rowmax[i], e);
      rowmax[j] = std::max(rowmax[j], e);
    }

  const char uplo = 'U';
  int info = 0, lwork = -1;
  double wq = 0.0;
  SBA_F77(dsytrf, DSYTRF)(&uplo, &m, a.data(), &m, ipiv.data(), &wq, &lwork, &info, 1);
  if (info != 0 || !workspace_size(wq, m, lwork)) return false;
  Vec work(std::size_t(lwork), 0.0);
  SBA_F77(dsytrf, DSYTRF)(&uplo, &m, a.data(), &m, ipiv.data(), work.data(), &lwork, &info, 1);
  if (info != 0) return false;

  const double tol = double(m) * kEps;
  IVec origin(static_cast<std::size_t>(m));
  for (int i = 0; i < m; ++i) origin[i] = i;
  for (int k = m - 1; k >= 0;) {
    if (ipiv[k] > 0) {
      std::swap(origin[k], origin[ipiv[k] - 1]);
      if (!(std::fabs(a[idx(k, k, m)]) > tol * rowmax[origin[k]])) return false;
      k -= 1;
    } else {
      if (k == 0 || ipiv[k - 1] != ipiv[k]) return false;  // not a pivot layout we know
      std::swap(origin[k - 1], origin[-ipiv[k] - 1]);
      const double p = a[idx(k - 1, k - 1, m)], q = a[idx(k - 1, k, m)], r = a[idx(k, k, m)];
      // Smallest eigenvalue magnitude as |det| / largest eigenvalue magnitude: Bunch-Kaufman
      // picks 2x2 blocks with a dominant off-diagonal, so det = p r - q^2 does not cancel.
      const double largest = std::fabs(0.5 * (p + r)) + std::hypot(0.5 * (p - r), q);
      const double smallest = largest > 0.0 ? std::fabs(p * r - q * q) / largest : 0.0;
      const double ref = std::max(rowmax[origin[k - 1]], rowmax[origin[k]]);
      if (!(smallest > tol * ref)) return false;
      k -= 2;
    }
  }
  return true;
}

// ---- the solvers: b holds the right-hand side on entry and the solution on success ----

bool solve_qr(const View &A, Vec &b) {
  const int m = A.m;
  Vec a = to_colmajor(A), tau(std::size_t(m), 0.0);
  if (!qr_factor(a, tau, m, double(m) * kEps, false)) return false;
  const Vec r = a;  // DORGQR overwrites R with Q

  int info = 0, lwork = -1;
  double wq = 0.0;
  SBA_F77(dorgqr, DORGQR)(&m, &m, &m, a.data(), &m, tau.data(), &wq, &lwork, &info);
  if (info != 0 || !workspace_size(wq, m, lwork)) return false;
  Vec work(std::size_t(lwork), 0.0);
  SBA_F77(dorgqr, DORGQR)(&m, &m, &m, a.data(), &m, tau.data(), work.data(), &lwork, &info);
  if (info != 0) return false;

  Vec y(std::size_t(m), 0.0);  // Q^T b
  for (int j = 0; j < m; ++j) {
    double s = 0.0;
    for (int i = 0; i < m; ++i) s += a[idx(i, j, m)] * b[i];
    y[j] = s;
  }
  if (!upper_solve(r, y, m, false)) return false;
  b.swap(y);
  return true;
}

// A^T A = R^T R, so x = R^-1 R^-T A^T b without forming Q: the semi-normal equations, whose
// condition number is that of A squared.
//  - Plain (sba_Axb_QRnoQ): one solve, R held to a stricter test than in plain QR (see the
//    file comment), so that the normal equations fail where they provably carry no digits.
//  - Refined (the `qrnoq` linear solver, on a diagonally scaled S): R only has to be
//    nonsingular, and corrected semi-normal refinement (x += (R^T R)^-1 A^T (b - A x), while
//    the residual keeps shrinking, at most 10 times) recovers the accuracy of QR itself, which
//    the varying-intrinsics problems need. When A is too ill-conditioned even for that, the
//    "solution" does not solve A x = b at all: a residual above 1e-12 ||b||^2 is a failure, so
//    that LM damps more.
bool qr_noq(const View &A, Vec &b, bool refined) {
  const int m = A.m;
  const std::size_t n = std::size_t(m);
  Vec a = to_colmajor(A), tau(n, 0.0);
  if (refined ? !qr_factor(a, tau, m, 0.0, false)
              : !qr_factor(a, tau, m, std::sqrt(double(m) * kEps), true))
    return false;
  // y = (R^T R)^-1 A^T v.
  auto seminormal = [&](const Vec &v, Vec &y) {
    for (int j = 0; j < m; ++j) {
      double s = 0.0;
      for (int i = 0; i < m; ++i) s += A(i, j) * v[i];
      y[j] = s;
    }
    return upper_solve(a, y, m, true) && upper_solve(a, y, m, false);
  };
  Vec x(n, 0.0);
  if (!seminormal(b, x)) return false;
  if (refined) {
    Vec res(n, 0.0), dx(n, 0.0);
    auto residual = [&]() {  // res = b - A x, and its squared norm
      double rn = 0.0;
      for (int i = 0; i < m; ++i) {
        double t = b[i];
        for (int j = 0; j < m; ++j) t -= A(i, j) * x[j];
        res[i] = t;
        rn += t * t;
      }
      return rn;
    };
    const double bn = dot(b, b);
    double rn = residual();
    for (int step = 0; step < 10 && rn > 0.0; ++step) {
      if (!seminormal(res, dx)) return false;
      for (std::size_t i = 0; i < n; ++i) x[i] += dx[i];
      const double next = residual();
      if (!(next < 0.25 * rn)) {  // no longer converging: rounding level reached, or diverging
        if (!(next <= rn))
          for (std::size_t i = 0; i < n; ++i) x[i] -= dx[i];
        rn = std::min(rn, next);
        break;
      }
      rn = next;
    }
    if (!(rn <= 1e-12 * bn)) return false;
  }
  b.swap(x);
  return true;
}

bool solve_qr_noq(const View &A, Vec &b) { return qr_noq(A, b, false); }
bool solve_qr_noq_refined(const View &A, Vec &b) { return qr_noq(A, b, true); }

bool solve_chol(const View &A, Vec &b) {
  const int m = A.m;
  Vec c = to_colmajor(A);
  if (!cholesky_upper(c, m, diagonal(c, m))) return false;
  const char uplo = 'U';
  const int nrhs = 1;
  int info = 0;
  SBA_F77(dpotrs, DPOTRS)(&uplo, &m, &nrhs, c.data(), &m, b.data(), &m, &info, 1);
  return info == 0;
}

// Unpivoted LDL^T (sba 1.6 declared sba_Axb_LDLt but never defined it). Reads the upper
// triangle of A. Without pivoting it suits SPD and quasi-definite matrices; any zero or
// rounding-level pivot (see the file comment) is a failure rather than a wild solution.
bool solve_ldlt(const View &A, Vec &b) {
  const int m = A.m;
  const double tol = double(m) * kEps;
  Vec l(std::size_t(m) * std::size_t(m), 0.0);  // unit lower triangular, column-major
  Vec d(std::size_t(m), 0.0), v(std::size_t(m), 0.0);
  for (int j = 0; j < m; ++j) {
    double s = A(j, j), ref = std::fabs(A(j, j));
    for (int k = 0; k < j; ++k) {
      v[k] = l[idx(j, k, m)] * d[k];
      const double t = l[idx(j, k, m)] * v[k];
      s -= t;
      ref += std::fabs(t);
    }
    if (!(std::fabs(s) > tol * ref)) return false;
    d[j] = s;
    l[idx(j, j, m)] = 1.0;
    for (int i = j + 1; i < m; ++i) {
      double t = A(j, i);  // = A(i, j), taken from the upper triangle
      for (int k = 0; k < j; ++k) t -= l[idx(i, k, m)] * v[k];
      l[idx(i, j, m)] = t / s;
    }
  }
  for (int i = 0; i < m; ++i)  // L y = b
    for (int k = 0; k < i; ++k) b[i] -= l[idx(i, k, m)] * b[k];
  for (int i = 0; i < m; ++i) b[i] /= d[i];
  for (int i = m - 1; i >= 0; --i)  // L^T x = y
    for (int k = i + 1; k < m; ++k) b[i] -= l[idx(k, i, m)] * b[k];
  return true;
}

bool solve_lu(const View &A, Vec &b) {
  const int m = A.m;
  Vec a = to_colmajor(A);
  IVec ipiv(std::size_t(m), 0);
  if (!lu_factor(a, ipiv, m)) return false;
  const char trans = 'N';
  const int nrhs = 1;
  int info = 0;
  SBA_F77(dgetrs, DGETRS)(&trans, &m, &nrhs, a.data(), &m, ipiv.data(), b.data(), &m, &info, 1);
  return info == 0;
}

bool solve_svd(const View &A, Vec &b) {
  const int m = A.m;
  const std::size_t mm = std::size_t(m) * std::size_t(m);
  Vec a = to_colmajor(A), s(std::size_t(m), 0.0), u(mm, 0.0), vt(mm, 0.0);
  IVec iwork(8 * std::size_t(m), 0);
  const char jobz = 'A';
  int info = 0, lwork = -1;
  double wq = 0.0;
  SBA_F77(dgesdd, DGESDD)(&jobz, &m, &m, a.data(), &m, s.data(), u.data(), &m, vt.data(), &m, &wq,
                          &lwork, iwork.data(), &info, 1);
  // The minimum for jobz = 'A' has changed between LAPACK releases; this bound covers the
  // largest of the documented ones for a square matrix.
  const long long mn = m;
  if (info != 0 || !workspace_size(wq, 7 * mn * mn + 8 * mn, lwork)) return false;
  Vec work(std::size_t(lwork), 0.0);
  SBA_F77(dgesdd, DGESDD)(&jobz, &m, &m, a.data(), &m, s.data(), u.data(), &m, vt.data(), &m,
                          work.data(), &lwork, iwork.data(), &info, 1);
  if (info != 0 || !(s[0] > 0.0) || !std::isfinite(s[0])) return false;

  const double cutoff = double(m) * kEps * s[0];
  Vec x(std::size_t(m), 0.0);
  for (int i = 0; i < m && s[i] > cutoff; ++i) {  // s is sorted descending
    double c = 0.0;
    for (int k = 0; k < m; ++k) c += u[idx(k, i, m)] * b[k];
    c /= s[i];
    for (int j = 0; j < m; ++j) x[j] += c * vt[idx(i, j, m)];
  }
  b.swap(x);
  return true;
}

bool solve_bk(const View &A, Vec &b) {
  const int m = A.m;
  Vec a = to_colmajor(A);
  IVec ipiv(std::size_t(m), 0);
  if (!bk_factor(a, ipiv, m)) return false;
  const char uplo = 'U';
  const int nrhs = 1;
  int info = 0;
  SBA_F77(dsytrs, DSYTRS)(&uplo, &m, &nrhs, a.data(), &m, ipiv.data(), b.data(), &m, &info, 1);
  return info == 0;
}

// ---- conjugate gradients ----

// q = A p, and qabs = |A| |p|, the scale against which p^T A p is judged.
void matvec(const View &A, const Vec &p, Vec &q, Vec *qabs) {
  const int m = A.m;
  for (int i = 0; i < m; ++i) {
    double s = 0.0, t = 0.0;
    for (int j = 0; j < m; ++j) {
      const double e = A(i, j) * p[j];
      s += e;
      t += std::fabs(e);
    }
    q[i] = s;
    if (qabs) (*qabs)[i] = t;
  }
}

// The preconditioners of sba_Axb_CG. SSOR with omega = 1 is M = (D + L) D^-1 (D + L^T),
// applied as a forward and a backward triangular sweep; it is SPD whenever A is, which keeps
// PCG well defined.
class Identity final : public Preconditioner {
 public:
  void apply(const Vec &r, Vec &z) const override { z = r; }
};

class Jacobi final : public Preconditioner {
 public:
  explicit Jacobi(const Vec &diag) : diag_(diag) {}
  void apply(const Vec &r, Vec &z) const override {
    for (std::size_t i = 0; i < r.size(); ++i) z[i] = r[i] / diag_[i];
  }

 private:
  const Vec &diag_;
};

class Ssor final : public Preconditioner {
 public:
  Ssor(const View &A, const Vec &diag) : A_(A), diag_(diag) {}
  void apply(const Vec &r, Vec &z) const override {
    const int m = A_.m;
    for (int i = 0; i < m; ++i) {
      double s = r[i];
      for (int j = 0; j < i; ++j) s -= A_(i, j) * z[j];
      z[i] = s / diag_[i];
    }
    for (int i = 0; i < m; ++i) z[i] *= diag_[i];
    for (int i = m - 1; i >= 0; --i) {
      double s = z[i];
      for (int j = i + 1; j < m; ++j) s -= A_(i, j) * z[j];
      z[i] = s / diag_[i];
    }
  }

 private:
  const View &A_;
  const Vec &diag_;
};

// How conjugate_gradients runs and when it stops.
struct CgControl {
  int maxit;
  double tol;  // the residual's norm to reach: eps ||b||_2
  bool warm;   // x holds the starting point (otherwise it is 0)
  // Exact (sba_Axb_CG): breakdown is a failure, and convergence is confirmed on the true
  // residual. Truncated (an inexact Newton step): breakdown after an update keeps the
  // iterate, the recurrence residual decides, and the norms are plain sums of squares, the
  // system being scaled to a unit diagonal.
  bool truncated;
};

// The one preconditioned CG iteration, for sba_Axb_CG and for truncated_cg. It returns
// iterations counted as sba 1.6 does, where an iteration tests the residual of the previous
// one and then updates x: k + 1 when the k-th update meets the tolerance (the test that sees
// it is the (k+1)-th iteration), maxit with x the last iterate when the budget runs out first
// (a tolerance met by the last update is not seen within the budget either), 0 on failure
// (x is then not to be used).
//
// Choices:
//  - An answer found without any update is the first iteration's test, reported as 1: b == 0
//    (x = 0, exact for a nonsingular A, whatever the starting point), and a caller-supplied
//    starting point (warm) whose residual already meets the tolerance, which is returned
//    as it is. Testing a warm start before the first update keeps a converged start from
//    being fed to the curvature test below with a residual at rounding level, where
//    p^T A p can drown in its own rounding and turn a correct answer into a failure.
//  - From x = 0 (not warm) at least one update is done for b != 0, even if eps >= 1.
//  - Exact: convergence is tested on the recurrence residual, then confirmed on the true
//    residual b - A x; if rounding has made them drift apart, the iteration restarts from the
//    true residual (the iteration count keeps running) rather than claiming a false
//    convergence.
//  - Running out of iterations is not an error, as in 1.6: the count is maxit and x is the
//    last iterate, so a caller can continue from it with niter < 0. A singular system with
//    an inconsistent right-hand side that does not break down ends this way too.
//  - Exact: breakdown is a failure: p^T A p not above its own rounding level
//    (m*eps*|p|^T |A| |p|) means A is not numerically positive definite along p. So is
//    r^T z <= 0 (M not SPD) or any NaN. Truncated: p^T A p <= 0 or r^T z <= 0 after an
//    update ends the iteration with the iterate reached.
int conjugate_gradients(const View &A, const Vec &b, Vec &x, const CgControl &c,
                        const Preconditioner &M) {
  const int m = A.m;
  const std::size_t n = std::size_t(m);
  auto norm = [&](const Vec &v) { return c.truncated ? std::sqrt(dot(v, v)) : norm2(v); };
  const double bnorm = norm(b);
  const double tol = c.tol * bnorm;
  const double curvature_tol = double(m) * kEps;

  if (bnorm == 0.0) {
    x.assign(n, 0.0);
    return 1;
  }

  Vec r = b, z(n, 0.0), p(n, 0.0), q(n, 0.0), qabs(n, 0.0);
  if (c.warm) {
    matvec(A, x, q, nullptr);
    for (std::size_t i = 0; i < n; ++i) r[i] = b[i] - q[i];
    if (!all_finite(r)) return 0;
    if (norm(r) <= tol) return 1;
  }
  M.apply(r, z);
  double rz = dot(r, z);
  if (!(rz > 0.0)) return 0;
  p = z;
  for (int k = 1; k <= c.maxit; ++k) {
    matvec(A, p, q, c.truncated ? nullptr : &qabs);
    const double pq = dot(p, q);
    if (c.truncated) {
      if (!(pq > 0.0)) return k > 1 && all_finite(x) ? k : 0;
    } else {
      double pqref = 0.0;
      for (std::size_t i = 0; i < n; ++i) pqref += std::fabs(p[i]) * qabs[i];
      if (!(pq > curvature_tol * pqref)) return 0;
    }
    const double alpha = rz / pq;
    for (std::size_t i = 0; i < n; ++i) {
      x[i] += alpha * p[i];
      r[i] -= alpha * q[i];
    }
    if (norm(r) <= tol) {
      if (c.truncated) return all_finite(x) ? k + 1 : 0;
      matvec(A, x, q, nullptr);
      for (std::size_t i = 0; i < n; ++i) r[i] = b[i] - q[i];
      if (norm(r) <= tol) return all_finite(x) ? std::min(k, c.maxit - 1) + 1 : 0;
      M.apply(r, z);
      rz = dot(r, z);
      if (!(rz > 0.0)) return 0;
      p = z;
      continue;
    }
    M.apply(r, z);
    const double rz_next = dot(r, z);
    if (!(rz_next > 0.0)) return c.truncated && all_finite(x) ? k : 0;
    const double beta = rz_next / rz;
    rz = rz_next;
    for (std::size_t i = 0; i < n; ++i) p[i] = z[i] + beta * p[i];
  }
  return all_finite(x) ? c.maxit : 0;
}

// sba_Axb_CG's solve: the preconditioner by its name, eps <= 0 for kDefaultCgEps.
int conjugate_gradients(const View &A, const Vec &b, Vec &x, bool warm, int maxit, double eps,
                        int prec) {
  const int m = A.m;
  if (prec != SBA_CG_NOPREC && prec != SBA_CG_JACOBI && prec != SBA_CG_SSOR) return 0;
  Vec diag(std::size_t(m), 0.0);
  for (int i = 0; i < m; ++i) {
    diag[i] = A(i, i);
    if (!(diag[i] > 0.0)) return 0;
  }
  const CgControl c{maxit, eps > 0.0 ? eps : kDefaultCgEps, warm, false};
  if (prec == SBA_CG_NOPREC) return conjugate_gradients(A, b, x, c, Identity());
  if (prec == SBA_CG_JACOBI) return conjugate_gradients(A, b, x, c, Jacobi(diag));
  return conjugate_gradients(A, b, x, c, Ssor(A, diag));
}

// ---- entry-point plumbing ----

using Solver = bool (*)(const View &, Vec &);

// The solve behind every helper; std::bad_alloc passes through.
bool solve_checked(Solver solve, const double *A, const double *B, double *x, int m, int iscolmaj) {
  const std::size_t n = std::size_t(m);
  if (!all_finite(A, n * n) || !all_finite(B, n)) return false;
  Vec sol(B, B + n);
  if (!solve(View(A, m, iscolmaj != 0), sol) || !all_finite(sol)) return false;
  std::copy(sol.begin(), sol.end(), x);
  return true;
}

// The solve of a method in any storage order.
Solver method_solver(Method method) {
  switch (method) {
    case Method::LDLt: return solve_ldlt;
    case Method::BK: return solve_bk;
    case Method::LU: return solve_lu;
    case Method::QR: return solve_qr;
    case Method::RefinedQRnoQ: return solve_qr_noq_refined;
    case Method::SVD: return solve_svd;
    case Method::Chol: return solve_chol;
    case Method::QRnoQ: return solve_qr_noq;
  }
  return nullptr;
}

}  // namespace

int axb(Method method, const double *A, const double *B, double *x, int m, int iscolmaj) noexcept {
  if (A == nullptr) return 1;
  if (m <= 0 || B == nullptr || x == nullptr) return 0;
  try {
    return solve_checked(method_solver(method), A, B, x, m, iscolmaj) ? 1 : 0;
  } catch (...) {
    return 0;
  }
}

int axb_cg(const double *A, const double *B, double *x, int m, int niter, double eps, int prec,
           int iscolmaj) noexcept {
  if (A == nullptr) return 1;
  if (m <= 0 || B == nullptr || x == nullptr) return 0;
  try {
    const std::size_t n = std::size_t(m);
    if (!all_finite(A, n * n) || !all_finite(B, n)) return 0;
    // niter < 0: x holds the starting point and -niter is the budget (INT_MIN has no
    // negation in int; its budget is INT_MAX). niter == 0 would be a budget of nothing if
    // taken literally; it means m iterations from x = 0, the most exact-arithmetic CG needs
    // (as sba.h documents).
    const bool warm = niter < 0;
    int maxit = m;
    if (niter > 0)
      maxit = niter;
    else if (warm)
      maxit = niter == std::numeric_limits<int>::min() ? std::numeric_limits<int>::max() : -niter;
    // Copied before anything is written, so x may alias B.
    const Vec rhs(B, B + n);
    Vec sol = warm ? Vec(x, x + n) : Vec(n, 0.0);
    if (!all_finite(sol)) return 0;
    const int iters =
        conjugate_gradients(View(A, m, iscolmaj != 0), rhs, sol, warm, maxit, eps, prec);
    if (iters <= 0) return 0;
    std::copy(sol.begin(), sol.end(), x);
    return iters;
  } catch (...) {
    return 0;
  }
}

namespace {

// The symmetric inverses, in sba 1.6's layout. A is row-major; only its upper triangle
// A[i*m+j], j >= i, is read, so the strictly lower triangle may hold anything, NaN
// included. The inverse goes to the lower triangle with the diagonal, A[i*m+j], j <= i,
// and the strictly upper triangle keeps the caller's input, so the caller still has the
// matrix it inverted. Inside, c holds the full symmetric matrix column-major for LAPACK
// (being symmetric, it reads the same in either order).
//
// Replaces the symmetric matrix in c by its inverse. For Cholesky and Bunch-Kaufman only
// the upper triangle of c is meaningful afterwards (DPOTRI and DSYTRI write no other);
// LU writes all of c, but symat_invert takes the upper triangle of every method's result, so
// the three agree on which of the two rounding-level variants of an off-diagonal entry
// they return.
bool invert(Vec &c, int m, Inverse how) {
  int info = 0;
  const char uplo = 'U';
  if (how == Inverse::LU) {
    IVec ipiv(std::size_t(m), 0);
    if (!lu_factor(c, ipiv, m)) return false;
    int lwork = -1;
    double wq = 0.0;
    SBA_F77(dgetri, DGETRI)(&m, c.data(), &m, ipiv.data(), &wq, &lwork, &info);
    if (info != 0 || !workspace_size(wq, m, lwork)) return false;
    Vec work(std::size_t(lwork), 0.0);
    SBA_F77(dgetri, DGETRI)(&m, c.data(), &m, ipiv.data(), work.data(), &lwork, &info);
    return info == 0;
  }
  if (how == Inverse::Chol) {
    if (!cholesky_upper(c, m, diagonal(c, m))) return false;
    SBA_F77(dpotri, DPOTRI)(&uplo, &m, c.data(), &m, &info, 1);
  } else {
    IVec ipiv(std::size_t(m), 0);
    if (!bk_factor(c, ipiv, m)) return false;
    Vec work(std::size_t(m), 0.0);
    SBA_F77(dsytri, DSYTRI)(&uplo, &m, c.data(), &m, ipiv.data(), work.data(), &info, 1);
  }
  return info == 0;
}

}  // namespace

// On failure (singular, not SPD for Cholesky, non-finite upper triangle, out of memory) A
// is left exactly as it was. 1.6's contract says nothing about A then; untouched is what
// lets a caller retry with another method on the same array.
int symat_invert(Inverse how, double *A, int m) noexcept {
  if (A == nullptr) return 1;
  if (m <= 0) return 0;
  try {
    const std::size_t n = std::size_t(m);
    Vec c(n * n);
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = i; j < n; ++j) {
        const double a = A[i * n + j];
        if (!std::isfinite(a)) return 0;
        c[i + j * n] = a;
        c[j + i * n] = a;
      }
    if (!invert(c, m, how)) return 0;
    for (std::size_t j = 0; j < n; ++j)
      for (std::size_t i = 0; i <= j; ++i)
        if (!std::isfinite(c[i + j * n])) return 0;
    // Row-major A[i*m+j] with j <= i receives the inverse's (j, i) = c(j, i), in c's upper
    // triangle.
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = 0; j <= i; ++j) A[i * n + j] = c[j + i * n];
    return 1;
  } catch (...) {
    return 0;
  }
}

// A^-1 = U^T U with U upper triangular: invert A through its Cholesky factor, then factor
// the inverse. Two O(m^3) steps, but both are plain LAPACK calls with the usual checks.
int mat_cholinv(const double *A, double *B, int m) noexcept {
  if (A == nullptr) return 1;
  if (m <= 0 || B == nullptr) return 0;
  try {
    const std::size_t mm = std::size_t(m) * std::size_t(m);
    if (!all_finite(A, mm)) return 0;
    Vec c = to_colmajor(View(A, m, false));
    if (!invert(c, m, Inverse::Chol)) return 0;
    if (!cholesky_upper(c, m, diagonal(c, m)) || !all_finite(c)) return 0;
    for (int i = 0; i < m; ++i)
      for (int j = 0; j < m; ++j)
        B[std::size_t(i) * std::size_t(m) + std::size_t(j)] = j >= i ? c[idx(i, j, m)] : 0.0;
    return 1;
  } catch (...) {
    return 0;
  }
}

namespace {

// The library's entry to a method: row-major A, std::bad_alloc passing through.
template <Solver method>
bool solve_rowmajor(const double *A, const double *b, double *x, int m) {
  if (!A || !b || !x || m <= 0) return false;
  return solve_checked(method, A, b, x, m, 0);
}

}  // namespace

Solve solver(Method method) {
  switch (method) {
    case Method::LDLt: return solve_rowmajor<solve_ldlt>;
    case Method::BK: return solve_rowmajor<solve_bk>;
    case Method::LU: return solve_rowmajor<solve_lu>;
    case Method::QR: return solve_rowmajor<solve_qr>;
    case Method::RefinedQRnoQ: return solve_rowmajor<solve_qr_noq_refined>;
    case Method::SVD: return solve_rowmajor<solve_svd>;
    case Method::Chol: return solve_rowmajor<solve_chol>;
    case Method::QRnoQ: return solve_rowmajor<solve_qr_noq>;
  }
  return nullptr;
}

bool truncated_cg(const double *A, const double *b, double *x, int m, int maxit, double rtol,
                  const Preconditioner &M) {
  if (!A || !b || !x || m <= 0 || maxit <= 0) return false;
  const std::size_t n = std::size_t(m);
  if (!all_finite(A, n * n) || !all_finite(b, n)) return false;
  const Vec rhs(b, b + n);
  Vec sol(n, 0.0);
  if (conjugate_gradients(View(A, m, false), rhs, sol, CgControl{maxit, rtol, false, true}, M) <= 0)
    return false;
  std::copy(sol.begin(), sol.end(), x);
  return true;
}

}  // namespace sba::dense
