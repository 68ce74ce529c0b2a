/* SPDX-License-Identifier: BSD-3-Clause */
/* A deliberately slow projection for the Ctrl-C test of the MEX interface: sbaeuc_proj
 * after a busy wait, so that a solve through 'sbaeuc_slowproj@...' runs long enough to be
 * interrupted while the library, not the interpreter, is working. */
#include <time.h>

void sbaeuc_proj(int j, int i, double *aj, double *bi, double *xij, double **adata);

void sbaeuc_slowproj(int j, int i, double *aj, double *bi, double *xij, double **adata) {
  const clock_t start = clock();
  while (clock() - start < CLOCKS_PER_SEC / 5000) { /* about 0.2 ms of CPU time */
  }
  sbaeuc_proj(j, i, aj, bi, xij, adata);
}
