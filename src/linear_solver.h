/* SPDX-License-Identifier: BSD-3-Clause */
// Which linear solver an LM solve uses, and the names callers choose it by (sba_ext_options,
// SBA_LINSOLVER). The solvers themselves and the factory that makes one from this choice:
// step_solver.h.
#ifndef SBA_SRC_LINEAR_SOLVER_H
#define SBA_SRC_LINEAR_SOLVER_H

#include <string>

namespace sba {

// How the damped normal equations are solved (see step_solver.h).
enum class LinSolver {
  Chol,        // dense S, Cholesky (sba 1.6's default): the library's own up to 2048 unknowns
  CholLapack,  // dense S, LAPACK's DPOTRF/DPOTRS at every size
  LDLt,        // dense S, unpivoted LDL^T
  BK,          // dense S, Bunch-Kaufman
  LU,          // dense S, LU
  QR,          // dense S, QR
  QRnoQ,       // dense S, QR without Q (R^T R x = S^T b)
  SVD,         // dense S, SVD
  CG,          // dense S, Jacobi-preconditioned conjugate gradients
  LdlAmd,      // no Schur complement: the whole system, AMD ordering + sparse LDL^T
  SparseChol,  // sparse S (cameras sharing points), CHOLMOD Cholesky
  IterativeSchur,  // S never formed: truncated CG on S x products, S's block diagonal as preconditioner
  Auto,        // one of chol, sparse-chol and iterative-schur, chosen from the problem (solver_choice.h)
  // One small Cholesky per free camera or point: what runs where the system is block diagonal
  // (block_diagonal, step_solver.h), whatever was asked. Named in reports, never chosen by name.
  BlockDiagonal,
};

// "chol", "ldlt", ... ; false for an unknown name.
bool linsolver_from_name(const std::string &name, LinSolver *out);
const char *linsolver_name(LinSolver s);
// Space-separated list of every name, for messages.
const char *linsolver_names();

}  // namespace sba

#endif
