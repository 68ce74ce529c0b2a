/* SPDX-License-Identifier: BSD-3-Clause */
/* Links against an installed sba and solves x = a_j + b_i with one fixed camera. */
#include <math.h>
#include <stdio.h>

#include <sba.h>
#include <sba_ext.h>

static void proj(int j, int i, double *aj, double *bi, double *xij, void *adata) {
  (void)j; (void)i; (void)adata;
  xij[0] = aj[0] + bi[0];
}

int main(void) {
  char vmask[4] = {1, 1, 1, 1};
  double p[4] = {0.0, 1.3, 0.8, 2.2}, x[4] = {1.0, 2.0, 2.0, 3.0}, info[SBA_INFOSZ];
  struct sba_ext_options ext;
  int ret;
  sba_ext_options_init(&ext);
  ext.linsolver = "sparse-chol";
  ret = sba_motstr_levmar_ext(2, 0, 2, 1, vmask, p, 1, 1, x, NULL, 1, proj, NULL, NULL, 50, 0, NULL,
                              info, &ext);
  if (ret <= 0 || fabs(p[1] - 1.0) > 1e-6) {
    fprintf(stderr, "consumer: ret %d p1 %g\n", ret, p[1]);
    return 1;
  }
  printf("consumer: ok, %s\n", SBA_VERSION);
  return 0;
}
