/* SPDX-License-Identifier: BSD-3-Clause */
// The linear solver "auto" stands for: chol, sparse-chol or iterative-schur, chosen from the
// problem's shape and a memory budget. The rule is a pure function of a few
// numbers (choose_linsolver), measured against the series of bench/auto_solver.py
// (docs/solvers.md has the figures); shape_of takes those numbers from a layout.
#ifndef SBA_SRC_SOLVER_CHOICE_H
#define SBA_SRC_SOLVER_CHOICE_H

#include <memory>
#include <string>

#include "layout.h"
#include "linear_solver.h"
#include "schur_pattern.h"

namespace sba {

// Up to this many camera unknowns a dense S is factored in about the time the other
// solvers take (or less), exactly, and the same bits for any thread count: chol.
constexpr i64 kDenseMaxUnknowns = 1000;
// Beyond that, sparse-chol when factoring S in its AMD order costs at most this many passes
// over the Jacobian (the work of one product S x of iterative-schur, which takes tens of
// them per step, and more where S is ill-conditioned); iterative-schur otherwise. The banded
// S of a camera path costs a few passes, the dense S of a photo collection hundreds to
// thousands.
constexpr double kSparseMaxPasses = 50;
// A factorization first forms S, where each point adds the products of its couplings to every
// pair of the blocks it touches: work that grows with the square of its track, where a product
// of iterative-schur's grows with the track. Long tracks make a pass costly and so the factor
// of a dense S look cheap in passes; past this many passes for forming S once (tracks of more
// than about a hundred cameras each, as where every point is seen by every image of a mapper's
// model), iterative-schur rather than sparse-chol, whatever the factor costs.
constexpr double kAssemblyMaxPasses = 400;

// What the choice looks at.
struct SolverShape {
  // The order of the reduced camera system S (the camera side's unknowns, after holding and
  // sharing) and its block rows (free cameras, or blocks of shared unknowns). 0 unknowns: no
  // choice to make (no free cameras, or no free points and nothing shared: the system is
  // block diagonal and solved block by block whatever the solver).
  i64 unknowns = 0, blocks = 0;
  // S's nonzero blocks and those of its Cholesky factor after an AMD ordering of its block
  // graph, each in the upper triangle with the diagonal, and that factorization's floating-
  // point operations. When S has too many blocks for a sparse factorization to be chosen,
  // shape_of stops counting: the factor is then taken as dense (blocks * (blocks + 1) / 2
  // blocks, unknowns^3 / 3 operations) and s_blocks is the count so far.
  i64 s_blocks = 0, factor_blocks = 0;
  double factor_flops = 0;
  bool s_partial = false;  // counting stopped: s_blocks is a lower bound
  // The floating-point operations of forming S once from the points' couplings: for each
  // free point, 2 pnp b b' for every pair of the blocks (of orders b, b') it touches.
  double assembly_flops = 0;
  i64 observations = 0;  // visible projections
  i64 points = 0;        // free points
  int cnp = 0, pnp = 0, mnp = 0;
  int jacobian_entry_bytes = 8;  // 4 with the Jacobian stored in single precision
  bool residual_kept = true;     // false when the solve streams it (single precision, lm_core.cpp)
  bool expert_index = true;      // the index's val array, kept for the expert callbacks
  // With shared unknowns (0 without): the free cameras' parameters, over which iterative-
  // schur's products run, and the doubles of its preconditioner's matrices, one per cluster
  // of S's blocks (iterative_schur_cluster_doubles). Without sharing, the parameters are the
  // unknowns and the preconditioner S's diagonal blocks.
  i64 shared_params = 0, cluster_doubles = 0;
  double budget_bytes = 0;  // memory the solve may plan with; 0: no budget (then anything fits)
  // S's pattern and AMD order when they were counted whole (not s_partial), for the sparse
  // solver to use as they are.
  std::shared_ptr<const SchurAnalysis> analysis;
};

// The floating-point operations of one pass over the Jacobian: every projection's mnp x
// (camera block + pnp) entries multiplied and added once.
double pass_flops(const SolverShape &s);

// Bytes each candidate needs: `common` for what every solve holds (Jacobian, residuals,
// normal equations' blocks, index), the others for the solver's own arrays. Measured against
// what the solves allocate in test_solver_choice (SolverMemory.*).
struct SolverMemory {
  double common = 0, chol = 0, sparse_chol = 0, iterative_schur = 0;
};
SolverMemory solver_memory(const SolverShape &s);
// common + the solver's own, for chol, sparse-chol or iterative-schur.
double solver_bytes(const SolverShape &s, LinSolver solver);

// The rule: chol, sparse-chol or iterative-schur for a problem of shape s (docs/solvers.md).
// Never one whose memory (solver_bytes) exceeds s.budget_bytes, unless none fits, in which
// case the one needing least (which the caller then refuses).
LinSolver choose_linsolver(const SolverShape &s);

// The shape and the memory in words, for the verbose line that says what auto chose and why.
std::string describe(const SolverShape &s);

// The shape of lay's problem, with budget_bytes as given.
SolverShape shape_of(const Layout &lay, double budget_bytes);

// The budget auto plans within: `asked` when positive (sba_ext_options.memory_budget), else the
// machine's physical memory, or the address-space limit (RLIMIT_AS) where lower. Settings, not
// readings of the moment's free memory, so that a problem is solved the same way, to the bit,
// whatever else runs. bytes 0: unknown (no physical memory size, no limit).
struct MemoryBudget {
  double bytes = 0;
  const char *what = "";  // where it comes from, for messages
};
MemoryBudget memory_budget(double asked);

}  // namespace sba

#endif
