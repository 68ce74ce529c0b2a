/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * The rotation of the Euclidean camera (euclidean.h) in plain C99, so that the C++ camera model
 * and the C callbacks of the MATLAB/Octave interface (matlab/sbaeuc_proj.c) compute it with the
 * same operations in the same order, and so get the same bits.
 *
 * Camera j keeps its input rotation q0_j; the optimizer sees only the vector part v of a small
 * correction qs = (w, u) = (sqrt(1 - |v|^2), v), and the camera's rotation is R(qs) R(q0_j).
 * Inside the unit ball u = v. Outside it sqrt would give a NaN that ends the whole solve (sba
 * treats a non-finite prediction as fatal), so a trial step that lands there is evaluated at
 * the nearest boundary rotation (w = 0, u = v/|v|) instead: the prediction stays finite and
 * continuous, and LM rejects the step on its error.
 *
 * The projection built on this rotation is not shared: the C++ model forms R(qs) R(q0) once
 * per camera and applies the product, the C callbacks apply R(q0) then R(qs), and the two
 * orders round differently.
 *
 * Matrices are row-major 3x3. Every function is static inline: the header has no object file
 * of its own and can be included by a file compiled alone (mex, mkoctfile).
 */
#ifndef SBA_LIB_CAMERAS_EUCLIDEAN_ROTATION_H
#define SBA_LIB_CAMERAS_EUCLIDEAN_ROTATION_H

#include <math.h>

/* The correction qs = (w, u) and its derivatives in v: dw/dv (3) and du/dv (3x3). */
typedef struct {
  double w;
  double u[3];
  double dw[3];
  double du[9];
} sbaeuc_correction;

static inline sbaeuc_correction sbaeuc_correction_of(const double v[3]) {
  sbaeuc_correction c;
  const double vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
  int r, s;
  for (r = 0; r < 9; ++r) c.du[r] = 0.0;
  if (vv < 1.0) {
    c.w = sqrt(1.0 - vv);
    for (r = 0; r < 3; ++r) {
      c.u[r] = v[r];
      c.dw[r] = -v[r] / c.w;
      c.du[r * 4] = 1.0;
    }
  } else {
    const double norm = sqrt(vv);
    c.w = 0.0;
    for (r = 0; r < 3; ++r) {
      c.u[r] = v[r] / norm;
      c.dw[r] = 0.0;
    }
    for (r = 0; r < 3; ++r)
      for (s = 0; s < 3; ++s) c.du[r * 3 + s] = ((r == s ? 1.0 : 0.0) - c.u[r] * c.u[s]) / norm;
  }
  return c;
}

/* R with R X = q X q^* for the unit quaternion q = w + x i + y j + z k. */
static inline void sbaeuc_rotation_matrix(double w, double x, double y, double z, double R[9]) {
  const double ww = w * w, xx = x * x, yy = y * y, zz = z * z;
  const double xy = x * y, xz = x * z, yz = y * z;
  const double wx = w * x, wy = w * y, wz = w * z;
  R[0] = ww + xx - yy - zz;
  R[1] = 2 * (xy - wz);
  R[2] = 2 * (xz + wy);
  R[3] = 2 * (xy + wz);
  R[4] = ww - xx + yy - zz;
  R[5] = 2 * (yz - wx);
  R[6] = 2 * (xz - wy);
  R[7] = 2 * (yz + wx);
  R[8] = ww - xx - yy + zz;
}

/* y = M x. */
static inline void sbaeuc_mat3_vec(const double M[9], const double x[3], double y[3]) {
  int r;
  for (r = 0; r < 3; ++r) y[r] = M[r * 3] * x[0] + M[r * 3 + 1] * x[1] + M[r * 3 + 2] * x[2];
}

/*
 * Jv = d(R(qs) Y)/dv (3x3). With R(qs) Y = Y + 2w (u x Y) + 2 u x (u x Y):
 *   d/du = -2w [Y]x + 2 ((u.Y) I + u Y^T - 2 Y u^T),   d/dw = 2 (u x Y),
 * then through du/dv and dw/dv.
 */
static inline void sbaeuc_rotation_derivative(const sbaeuc_correction *qs, const double Y[3],
                                              double Jv[9]) {
  const double *u = qs->u;
  const double uY = u[0] * Y[0] + u[1] * Y[1] + u[2] * Y[2];
  const double uxY[3] = {u[1] * Y[2] - u[2] * Y[1], u[2] * Y[0] - u[0] * Y[2],
                         u[0] * Y[1] - u[1] * Y[0]};
  const double Yx[9] = {0, -Y[2], Y[1], Y[2], 0, -Y[0], -Y[1], Y[0], 0};
  double dRY_du[9];
  int r, c;
  for (r = 0; r < 3; ++r)
    for (c = 0; c < 3; ++c)
      dRY_du[r * 3 + c] =
          -2 * qs->w * Yx[r * 3 + c] + 2 * ((r == c ? uY : 0.0) + u[r] * Y[c] - 2 * Y[r] * u[c]);
  for (r = 0; r < 3; ++r)
    for (c = 0; c < 3; ++c)
      Jv[r * 3 + c] = dRY_du[r * 3] * qs->du[c] + dRY_du[r * 3 + 1] * qs->du[3 + c] +
                      dRY_du[r * 3 + 2] * qs->du[6 + c] + 2 * uxY[r] * qs->dw[c];
}

#endif /* SBA_LIB_CAMERAS_EUCLIDEAN_ROTATION_H */
