/* SPDX-License-Identifier: BSD-3-Clause */
// The dense factorizations of the reduced camera system S, behind one interface and chosen
// once per solve (the way Ceres picks its dense Cholesky backend): the dense Schur solver
// picks one for its linear solver (make_dense_factorization, step_solver.h), assembles S where
// the factorization asks for it and hands it over.
#ifndef SBA_SRC_DENSE_FACTORIZATION_H
#define SBA_SRC_DENSE_FACTORIZATION_H

#include <memory>

#include "dense.h"
#include "parallel.h"
#include "types.h"

namespace sba {

class DenseFactorization {
 public:
  virtual ~DenseFactorization() = default;
  // The row stride (>= n) of the row-major S that solve expects.
  i64 ld() const { return ld_; }
  // x = S^-1 rhs for the damped (positive definite) S of order n, given as its upper triangle
  // (row-major, row stride ld(), as the dense assembly leaves it). S's storage, rhs and its
  // rows' padding are the factorization's to overwrite. False when S cannot be factored (x
  // may then hold anything); on success x may still hold non-finite entries, which the caller
  // tests.
  virtual bool solve(double *S, double *rhs, double *x) = 0;

 protected:
  DenseFactorization(i64 n, i64 ld) : n_(n), ld_(ld) {}
  i64 n_, ld_;
};

// The factorizations of S of order n:
// Cholesky, the library's own up to the order where LAPACK's is faster, LAPACK's beyond;
std::unique_ptr<DenseFactorization> make_cholesky(i64 n, ThreadPool &pool);
// LAPACK's Cholesky (DPOTRF/DPOTRS) at every order;
std::unique_ptr<DenseFactorization> make_lapack_cholesky(i64 n, ThreadPool &pool);
// a method of the sba_Axb_* helpers (dense.h), on S scaled to a unit diagonal;
std::unique_ptr<DenseFactorization> make_axb_factorization(dense::Method method, i64 n, ThreadPool &pool);
// the SVD's pseudo-solve (sba_Axb_SVD's) on S scaled the same, the unknowns that S leaves
// uncoupled (a camera that sees no point) solved alone;
std::unique_ptr<DenseFactorization> make_svd(i64 n, ThreadPool &pool);
// conjugate gradients preconditioned by S's cnp x cnp diagonal blocks, on S scaled the same.
std::unique_ptr<DenseFactorization> make_block_jacobi_cg(i64 n, int cnp, ThreadPool &pool);

// The library's own dense Cholesky (src/dense_chol_impl.h) in the build the CPU runs (isa.h):
// S = U^T U in place (S row-major upper with row stride ld; U in the same place, LAPACK's
// column-major lower factor), and U^-T b for nrhs right-hand sides b held in columns
// [n, n + nrhs) of the rows (ld >= n + nrhs). Every entry is computed as the unblocked
// right-looking algorithm computes it, so the bits do not depend on the number of threads.
// False if S is not numerically positive definite. Defined in dense_chol.cpp.
using DenseCholesky = bool (*)(ThreadPool &pool, double *S, i64 n, i64 ld, i64 nrhs);
DenseCholesky own_dense_cholesky();

}  // namespace sba

#endif
