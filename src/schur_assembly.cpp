// SPDX-License-Identifier: BSD-3-Clause
#include "schur_assembly.h"

namespace sba {

SchurAssembly::SchurAssembly(const SolveContext &ctx) : ctx_(ctx) {
  const Layout &lay = ctx.lay;
  if (lay.cams.per_camera()) return;
  schur_ = std::make_unique<MappedSchur>(lay, ctx.pool.size());
  Vinv_.resize(size_t(lay.n) * size_t(lay.pnp) * size_t(lay.pnp));
  du_.resize(size_t(lay.camera_unknowns()));
}

bool SchurAssembly::assemble(const NormalEquations &ne, double mu, const BlockMap &cams,
                             const UnknownBlocks &unknowns, double *rhs) {
  // The point blocks' inverses are made where they are used rather than kept (n pnp^2
  // doubles, as much as S itself on a long sequence), unless the mapped assembly needs them.
  if (!schur_) return ctx_.kernels.assemble(ctx_.pool, ne, nullptr, mu, cams, rhs);
  if (ctx_.lay.free_pts() > 0 && !ctx_.kernels.invert_damped_V(ctx_.pool, ne.V, mu, Vinv_.data())) return false;
  schur_->assemble(ctx_.pool, ne, Vinv_.data(), mu, unknowns, rhs);
  return true;
}

double *SchurAssembly::solution(double *dp) {
  return schur_ ? du_.data() : dp + ctx_.lay.a_off(ctx_.lay.mcon);
}

void SchurAssembly::finish(const NormalEquations &ne, double mu, double *dp) {
  const Layout &lay = ctx_.lay;
  if (schur_) lay.cams.expand(du_.data(), -0.0, dp);
  if (lay.free_pts() > 0) ctx_.kernels.back_substitute(ctx_.pool, ne, schur_ ? Vinv_.data() : nullptr, mu, dp);
}

}  // namespace sba
