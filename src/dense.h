/* SPDX-License-Identifier: BSD-3-Clause */
// The dense solvers of sba.h's helpers: the helpers themselves, with sba.h's contract, which
// the C boundary exports (c_api_dense.cpp), and the same solvers for the library's own use.
// The helpers turn every failure into a return value of 0, including running out of memory,
// which the LM loop would take for a failed factorization and answer with more damping; for
// the library's use std::bad_alloc passes through, so that a solve out of memory ends in
// SBA_ERROR.
#ifndef SBA_SRC_DENSE_H
#define SBA_SRC_DENSE_H

#include <vector>

namespace sba::dense {

// LDLt, BK, LU, QR, SVD, Chol, QRnoQ: as the matching sba_Axb_* helper. RefinedQRnoQ: the
// semi-normal equations of QR without Q (as sba_Axb_QRnoQ), without its strict test on R's
// diagonal but followed by corrected semi-normal refinement, and failing when the refined
// residual is not small (see dense.cpp).
enum class Method { LDLt, BK, LU, QR, RefinedQRnoQ, SVD, Chol, QRnoQ };

// ---- sba.h's helpers, with its contract (dense.cpp's opening comment) ----
// None of them throws: every failure, running out of memory included, returns 0.

// sba_Axb_<method>(A, B, x, m, iscolmaj).
int axb(Method method, const double *A, const double *B, double *x, int m, int iscolmaj) noexcept;
// sba_Axb_CG(A, B, x, m, niter, eps, prec, iscolmaj).
int axb_cg(const double *A, const double *B, double *x, int m, int niter, double eps, int prec,
           int iscolmaj) noexcept;
// sba_symat_invert_<how>(A, m).
enum class Inverse { LU, Chol, BK };
int symat_invert(Inverse how, double *A, int m) noexcept;
// sba_mat_cholinv(A, B, m).
int mat_cholinv(const double *A, double *B, int m) noexcept;

// ---- for the library ----

// Solves A x = b for the row-major m x m A (none of them writes A or b); false when it fails
// (singular, not finite). May throw std::bad_alloc.
using Solve = bool (*)(const double *A, const double *b, double *x, int m);

// The solve of a method, looked up once by a caller that solves many systems.
Solve solver(Method method);

// z = M^-1 r for a symmetric positive definite M, the preconditioner of conjugate_gradients.
class Preconditioner {
 public:
  virtual ~Preconditioner() = default;
  virtual void apply(const std::vector<double> &r, std::vector<double> &z) const = 0;
};

// Truncated (inexact Newton) preconditioned CG on the row-major SPD m x m A from x = 0: at most
// maxit iterations, stopping at ||b - A x||_2 <= rtol ||b||_2 on the recurrence residual.
// Every iterate from 0 lowers the quadratic model, so running out of iterations is a success
// (x is the last iterate), and so is a loss of curvature (p^T A p <= 0) or of M's
// definiteness after at least one update (x is the iterate before it). False before any
// update, or when the result is not finite. May throw std::bad_alloc.
bool truncated_cg(const double *A, const double *b, double *x, int m, int maxit, double rtol,
                  const Preconditioner &M);

}  // namespace sba::dense

#endif
