/* SPDX-License-Identifier: BSD-3-Clause */
/* sbatest_focal_proj.m as a C callback for the 'NAME@LIBRARY' route: the tests of the options
 * struct solve its scene many times with finite-difference Jacobians, a dozen projections per
 * observation and iteration, which the interpreter makes the bulk of their time. The formula
 * is the .m file's: aj = [w t f], w the rotation as an axis times its angle (Rodrigues), t the
 * translation, f the focal length; bi the 3D point. */
#include <math.h>

void sbatest_focal_proj(int j, int i, double *aj, double *bi, double *xij, double **adata) {
  (void)j;
  (void)i;
  (void)adata;
  const double th = sqrt(aj[0] * aj[0] + aj[1] * aj[1] + aj[2] * aj[2]);
  double R[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  if (th != 0) {
    const double k[3] = {aj[0] / th, aj[1] / th, aj[2] / th};
    const double K[3][3] = {{0, -k[2], k[1]}, {k[2], 0, -k[0]}, {-k[1], k[0], 0}};
    const double s = sin(th), c = 1 - cos(th);
    for (int r = 0; r < 3; ++r)
      for (int q = 0; q < 3; ++q) {
        const double KK = K[r][0] * K[0][q] + K[r][1] * K[1][q] + K[r][2] * K[2][q];
        R[r][q] += s * K[r][q] + c * KK;
      }
  }
  double X[3];
  for (int r = 0; r < 3; ++r)
    X[r] = R[r][0] * bi[0] + R[r][1] * bi[1] + R[r][2] * bi[2] + aj[3 + r];
  xij[0] = aj[6] * X[0] / X[2];
  xij[1] = aj[6] * X[1] / X[2];
}
