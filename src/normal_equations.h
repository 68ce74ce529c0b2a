/* SPDX-License-Identifier: BSD-3-Clause */
// The normal equations of an LM iteration, the vocabulary that the block kernels, the linear
// solvers and the covariance share: the Jacobian blocks A_ij, B_ij and what is formed from
// them, U_j = sum_i A_ij^T A_ij, V_i = sum_j B_ij^T B_ij, W_ij = A_ij^T B_ij.
#ifndef SBA_SRC_NORMAL_EQUATIONS_H
#define SBA_SRC_NORMAL_EQUATIONS_H

#include "layout.h"

namespace sba {

// The normal equations of the current (weighted) Jacobian: the undamped U_j, V_i and
// e_a = A^T e, e_b = B^T e. Blocks of fixed cameras and points are not meaningful.
struct NormalEquations {
  const double *jac = nullptr;  // callback layout: A_ij then B_ij per projection
  const double *U = nullptr, *V = nullptr, *ea = nullptr, *eb = nullptr;
};

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

}  // namespace sba

#endif
