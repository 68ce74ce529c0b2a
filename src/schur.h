/* SPDX-License-Identifier: BSD-3-Clause */
// Small pieces of the Schur complement shared by the solvers and the covariance.
#ifndef SBA_SRC_SCHUR_H
#define SBA_SRC_SCHUR_H

#include "step_solver.h"

namespace sba::schur {

// W_ij = A_ij^T B_ij (cnp x pnp, row-major) of projection k.
inline void form_W(const Layout &lay, const double *jac, i64 k, double *W) {
  const int mnp = lay.mnp, cnp = lay.cnp, pnp = lay.pnp;
  const double *A = jac + k * lay.jblk();
  const double *B = A + mnp * cnp;
  for (int a = 0; a < cnp; ++a)
    for (int b = 0; b < pnp; ++b) {
      double s = 0.0;
      for (int r = 0; r < mnp; ++r) s += A[r * cnp + a] * B[r * pnp + b];
      W[a * pnp + b] = s;
    }
}

}  // namespace sba::schur

#endif
