/* SPDX-License-Identifier: BSD-3-Clause */
/* A caller written for sba 1.5 (no ncon argument) compiles unchanged with -DSBA_API_1_5. */
#include <stdio.h>

#include "sba.h"

static void proj(int j, int i, double *aj, double *bi, double *xij, void *adata) {
  (void)j; (void)i; (void)adata;
  xij[0] = aj[0] + bi[0];
}

int main(void) {
  char vmask[4] = {1, 1, 1, 1};
  double p[4] = {0.0, 1.2, 0.9, 2.1}, x[4] = {1.0, 2.0, 2.0, 3.0}, info[SBA_INFOSZ];
  /* 1.5 argument list: n, m, mcon, vmask, p, cnp, pnp, x, covx, mnp, proj, projac, ... */
  int ret = sba_motstr_levmar(2, 2, 1, vmask, p, 1, 1, x, NULL, 1, proj, NULL, NULL, 50, 0, NULL, info);
  if (ret <= 0 || info[1] > 1e-12) {
    fprintf(stderr, "1.5-style call failed: ret %d, error %g\n", ret, info[1]);
    return 1;
  }
  printf("1.5 API: ok (%d iterations)\n", ret);
  return 0;
}
