/* SPDX-License-Identifier: BSD-3-Clause */
// sba_chkjac.h's Jacobian checks as one call: the caller's index and callbacks checked, made
// into a model, and handed to check_jacobian (jacobian_check.h).
#ifndef SBA_SRC_CHKJAC_DRIVER_H
#define SBA_SRC_CHKJAC_DRIVER_H

#include "layout.h"
#include "model.h"

namespace sba {

// One sba_*_chkjac_x call's arguments, in the motion+structure shape (the sizes a mode has no
// use for are 0).
struct ChkjacArgs {
  const char *name;
  Mode mode;
  ExpertFunc func, jacf;
  double *p;
  sba_crsm *idx;
  int *rcidxs, *rcsubs;
  int ncon, mcon, cnp, pnp, mnp;
  void *func_adata, *jac_adata;
};

// Checks the arguments, then the Jacobian, printing the findings on stderr; nothing is thrown
// but a forced unwind (log.h, catch_all).
void run_chkjac(const ChkjacArgs &a);

}  // namespace sba

#endif
