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
#include "parallel.h"
#include "schur_pattern.h"

namespace sba {

class DenseFactorization;

// What every solver works with: the problem, the threads, the block kernels; and, when the
// choice of solver has made them (auto), S's pattern and its ordering, which the sparse
// solver then takes as they are.
struct SolveContext {
  const Layout &lay;
  ThreadPool &pool;
  const Kernels &kernels;
  const SchurAnalysis *analysis = nullptr;
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
  // Whether solve() damps each parameter q by mu ne.damping[q] when ne.damping is set (the
  // trust region's Marquardt damping without a change of variables); a solver that does not
  // is handed ne.damping null, and the strategy scales the normal equations instead.
  virtual bool takes_damping() const { return false; }
};

// Whether lay's normal equations are block diagonal: no free points or no free cameras (the
// motion-only and structure-only drivers, mcon == m, ncon == n), unless cameras share
// unknowns, which couples them without any point.
bool block_diagonal(const Layout &lay);

// The solver for a problem. A block diagonal one (block_diagonal) always uses per-block
// Cholesky (LinSolver::BlockDiagonal), whatever `kind` says. Each
// solver works over the layout's camera unknowns (camera_map.h): sba 1.6's per-camera
// blocks, or the blocks of shared unknowns.
std::unique_ptr<StepSolver> make_step_solver(LinSolver kind, const SolveContext &ctx);

// make_step_solver: step_solver.cpp; the others: solver_*.cpp.
std::unique_ptr<StepSolver> make_dense_schur_solver(LinSolver kind, const SolveContext &ctx);
// The factorization of S behind a dense linear solver (Chol, CholLapack, LDLt, BK, LU, QR,
// QRnoQ, SVD, CG: dense_factorization.h) for S of order n made of cnp x cnp camera blocks;
// null for any other kind. make_dense_schur_solver's choice, declared for the tests.
std::unique_ptr<DenseFactorization> make_dense_factorization(LinSolver kind, i64 n, int cnp, ThreadPool &pool);
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
// z = M^-1 r over S's unknowns, M the iterative solver's preconditioner at damping mu; false
// as the solver fails. For the tests.
bool iterative_schur_apply_preconditioner(const SolveContext &ctx, const NormalEquations &ne, double mu,
                                          const double *r, double *z);
// The doubles of the iterative solver's preconditioner over map's shared unknowns: a matrix
// per cluster of S's blocks, its order squared. For auto's memory estimate (solver_choice.h).
i64 iterative_schur_cluster_doubles(const CameraMap &map);
// One step of the iterative solver at damping mu into dp: its CG iterations, or -1 if it
// failed; with shared unknowns, clusters false preconditions with S's diagonal blocks alone
// instead of its clusters. For the tests.
int iterative_schur_cg_iterations(const SolveContext &ctx, const NormalEquations &ne, double mu, double *dp,
                                  bool clusters = true);

}  // namespace sba

#endif
