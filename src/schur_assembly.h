/* SPDX-License-Identifier: BSD-3-Clause */
// The reduced camera system S and its right-hand side assembled over the layout's camera map
// (camera_map.h), whichever its shape, for the solvers that form S (dense and sparse), and
// the step put together from S's solution: the cameras' parameters and the points' steps by
// back-substitution. In the PerCamera shape the block kernels (kernels.h) assemble S at their
// fixed sizes and make each point's (V_i + mu I)^-1 where they use it; in the Blocks shape
// the mapped assembly (mapped_schur.h) takes them made, and S's solution is over the unknowns.
#ifndef SBA_SRC_SCHUR_ASSEMBLY_H
#define SBA_SRC_SCHUR_ASSEMBLY_H

#include <memory>
#include <vector>

#include "kernels.h"
#include "mapped_schur.h"
#include "step_solver.h"

namespace sba {

class SchurAssembly {
 public:
  explicit SchurAssembly(const SolveContext &ctx);

  // S at damping mu into the storage the shape reads, `cams` (PerCamera) or `unknowns`
  // (Blocks), both describing the same matrix, and rhs (S's order); false if some free
  // point's V_i + mu I is singular.
  bool assemble(const NormalEquations &ne, double mu, const BlockMap &cams, const UnknownBlocks &unknowns,
                double *rhs);
  // Where S's solution goes for the step dp: dp's free cameras themselves in the PerCamera
  // shape, a vector of the unknowns otherwise.
  double *solution(double *dp);
  // dp from S's solution (in solution(dp)): every camera parameter's, then the points'.
  void finish(const NormalEquations &ne, double mu, double *dp);

 private:
  const SolveContext ctx_;
  std::unique_ptr<MappedSchur> schur_;  // the Blocks shape's assembly
  std::vector<double> Vinv_, du_;       // its points' inverses, and S's solution
};

}  // namespace sba

#endif
