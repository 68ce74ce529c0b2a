// Small pieces shared by the solvers.
#ifndef SBA_SRC_SCHUR_H
#define SBA_SRC_SCHUR_H

#include "linsolve.h"

namespace sba::schur {

// W_ij = A_ij^T B_ij (cnp x pnp, row-major) of projection k.
void form_W(const Layout &lay, const double *jac, i64 k, double *W);

}  // namespace sba::schur

#endif
