/* SPDX-License-Identifier: BSD-3-Clause */
// The linear solvers of the augmented normal equations, chosen at run time behind one
// interface. Each LM iteration computes the undamped normal equations once; a StepSolver
// turns them into the damped step for as many damping values as the iteration tries.
#ifndef SBA_SRC_STEP_SOLVER_H
#define SBA_SRC_STEP_SOLVER_H

#include <memory>
#include <vector>

#include "kernels.h"
#include "layout.h"
#include "linear_solver.h"
#include "normal_equations.h"
#include "parallel.h"

namespace sba {

// What every solver works with: the problem, the threads, the block kernels.
struct SolveContext {
  const Layout &lay;
  ThreadPool &pool;
  const Kernels &kernels;
};

// What became of one damped solve. sba 1.6 counts an attempt as a linear system once its
// point blocks are inverted: an attempt that ends at a singular V_i + mu I is not counted.
enum class StepStatus {
  Solved,
  SingularPointBlock,  // some free point's V_i + mu I is singular
  Failed,              // the damped system cannot be solved at this mu
};

class StepSolver {
 public:
  virtual ~StepSolver() = default;
  // dp (all nvars entries; fixed ones set to 0) solving (J^T J + mu I) dp = J^T e on the
  // free parameters, where U and V are ne's blocks as they are (sba 1.6's retries hand them
  // over with the diagonals its previous attempts left: strategy.h, before_retry).
  virtual StepStatus solve(const NormalEquations &ne, double mu, double *dp) = 0;
  // After solve() returned Solved at damping mu: dp for another right-hand side, ne's e_a and
  // e_b (its other blocks those solve() had), reusing what solve() factored. False when the
  // solver keeps nothing to reuse or the solution is not finite: the caller then calls
  // solve(). Held and shared camera parameters (camera_params.h) solve one system for
  // several right-hand sides.
  virtual bool solve_again(const NormalEquations &ne, double mu, double *dp) {
    (void)ne, (void)mu, (void)dp;
    return false;
  }
};

// rhs = e_a - W V*^-1 e_b over the free cameras, what Kernels::assemble makes beside S, for
// the Schur solvers' solve_again: a right-hand side other than the one S was assembled with.
class ReducedRhs {
 public:
  explicit ReducedRhs(const SolveContext &ctx) : ctx_(ctx) {}
  // S has been assembled again: the point blocks' inverses kept are no longer its.
  void reset() { have_vinv_ = false; }
  // mu: the damping S was assembled with. The point blocks' inverses are those of every
  // right-hand side at that damping, so they are made on the first call after reset() only.
  // False if some V_i + mu I is not positive definite.
  bool operator()(const NormalEquations &ne, double mu, double *rhs);
  // Kernels::invert_damped_V's blocks of the last call, for back_substitute.
  const double *Vinv() const { return Vinv_.data(); }

 private:
  SolveContext ctx_;
  std::vector<int> row_, k_;  // the index by camera, made on first use
  std::vector<double> y_;     // V*^-1 e_b, per point
  std::vector<double> Vinv_;
  bool have_vinv_ = false;  // Vinv_ made since the last reset()
};

// The solver for a problem. Problems without free points or without free cameras (the
// motion-only and structure-only drivers, mcon == m, ncon == n) are block diagonal and
// always use per-block Cholesky, whatever `kind` says.
std::unique_ptr<StepSolver> make_step_solver(LinSolver kind, const SolveContext &ctx);

// make_step_solver: step_solver.cpp; the others: solver_*.cpp.
std::unique_ptr<StepSolver> make_dense_schur_solver(LinSolver kind, const SolveContext &ctx);
std::unique_ptr<StepSolver> make_ldl_amd_solver(const SolveContext &ctx);
std::unique_ptr<StepSolver> make_sparse_schur_solver(const SolveContext &ctx);
std::unique_ptr<StepSolver> make_iterative_schur_solver(const SolveContext &ctx);
// y = S x (S = U* - W V*^-1 W^T over the free cameras, at damping mu) as the iterative
// solver computes it, never forming S; false if some V_i + mu I is not positive definite.
// For the tests.
bool iterative_schur_product(const SolveContext &ctx, const NormalEquations &ne, double mu,
                             const double *x, double *y);
// The iterative solver's preconditioner at damping mu: S's diagonal block of each free
// camera, Cholesky-factored (L in the lower triangle of each cnp x cnp block of D, row-major;
// above it, whatever the factorization left). False as the solver fails. For the tests.
bool iterative_schur_preconditioner(const SolveContext &ctx, const NormalEquations &ne, double mu, double *D);

}  // namespace sba

#endif
