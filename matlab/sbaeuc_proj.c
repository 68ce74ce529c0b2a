/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * The Euclidean camera of eucsbademo (fixed intrinsics) as C callbacks for sba's MATLAB / Octave
 * gateway: pass 'NAME@LIBRARY' strings such as 'sbaeuc_proj@libsbaeuc_proj.so' to sba(). They
 * compute what sbaeuc_proj.m, sbaeuc_projac.m, sbaeuc_projac_mot.m and sbaeuc_projac_str.m
 * compute, far faster than the interpreted versions.
 *
 * Model (see sbaeuc_proj.m for the full statement):
 *   a_j = (v1 v2 v3 t1 t2 t3): the vector part of a small rotation qs = (sqrt(1-|v|^2), v)
 *         applied after the camera's initial rotation q0_j, then the translation t;
 *   b_i = (X Y Z): a point;
 *   x_ij = K * dehomogenize(R(qs) R(q0_j) b_i + t), K = [fu s u0; 0 fu*ar v0; 0 0 1].
 * Extra data (adata[k] points to the doubles of the k-th extra argument of sba):
 *   adata[0]: qr0, the 4*m initial unit quaternions (w x y z per camera, w >= 0);
 *   adata[1]: cal = (fu u0 v0 ar s).
 * Outside the unit ball (|v| >= 1, only ever reached by a rejected trial step) qs is the
 * boundary rotation (0, v/|v|), which keeps the prediction finite and continuous.
 * Without the two extra arguments (adata[0] or adata[1] NULL) every output is NaN, so the
 * solve stops with a NaN error instead of reading through a null pointer; qr0 must still
 * hold 4 values per camera, which C cannot check.
 *
 * Jacobians are row-major: A_ij is 2 x 6, B_ij is 2 x 3.
 */
#include <math.h>
#include <stddef.h>

/* The rotation, shared with eucsbademo's camera model. */
#include "../lib/cameras/euclidean_rotation.h"

#if defined(__GNUC__)
#define SBAEUC_EXPORT __attribute__((visibility("default")))
#else
#define SBAEUC_EXPORT
#endif

/* The projection of b by camera j with parameters a; A (2x6) and B (2x3) unless NULL. */
static void euclidean(int j, const double *a, const double *b, double **adata, double *x, double *A,
                      double *B) {
  if (!adata || !adata[0] || !adata[1]) { /* qr0 or cal missing from the call of sba */
    int k;
    for (k = 0; k < 12; ++k) {
      if (x && k < 2) x[k] = NAN;
      if (A) A[k] = NAN;
      if (B && k < 6) B[k] = NAN;
    }
    return;
  }
  const double *q0 = adata[0] + 4 * j, *cal = adata[1];
  const double fu = cal[0], u0 = cal[1], v0 = cal[2], ar = cal[3], sk = cal[4], fv = fu * ar;
  const sbaeuc_correction qs = sbaeuc_correction_of(a);
  double R0[9], Rs[9], Y[3], Xc[3], iz, xn, yn, H[6];
  int r, c;

  sbaeuc_rotation_matrix(q0[0], q0[1], q0[2], q0[3], R0);
  sbaeuc_mat3_vec(R0, b, Y); /* Y = R(q0) b */
  sbaeuc_rotation_matrix(qs.w, qs.u[0], qs.u[1], qs.u[2], Rs);
  sbaeuc_mat3_vec(Rs, Y, Xc);
  for (r = 0; r < 3; ++r) Xc[r] += a[3 + r];
  iz = 1.0 / Xc[2];
  xn = Xc[0] * iz;
  yn = Xc[1] * iz;
  if (x) {
    x[0] = fu * xn + sk * yn + u0;
    x[1] = fv * yn + v0;
  }
  if (!A && !B) return;

  /* H = d pixel / d Xc = [fu s; 0 fv] * [1/Z 0 -X/Z^2; 0 1/Z -Y/Z^2] */
  H[0] = fu * iz;
  H[1] = sk * iz;
  H[2] = -(fu * xn + sk * yn) * iz;
  H[3] = 0.0;
  H[4] = fv * iz;
  H[5] = -fv * yn * iz;

  if (B) { /* d Xc / d b = Rs R0 */
    double RsR0[9];
    for (r = 0; r < 3; ++r)
      for (c = 0; c < 3; ++c)
        RsR0[r * 3 + c] = Rs[r * 3] * R0[c] + Rs[r * 3 + 1] * R0[3 + c] + Rs[r * 3 + 2] * R0[6 + c];
    for (r = 0; r < 2; ++r)
      for (c = 0; c < 3; ++c)
        B[r * 3 + c] = H[r * 3] * RsR0[c] + H[r * 3 + 1] * RsR0[3 + c] + H[r * 3 + 2] * RsR0[6 + c];
  }
  if (A) { /* d Xc / d v = d(R(qs) Y) / dv */
    double Jv[9];
    sbaeuc_rotation_derivative(&qs, Y, Jv);
    for (r = 0; r < 2; ++r)
      for (c = 0; c < 3; ++c) {
        A[r * 6 + c] = H[r * 3] * Jv[c] + H[r * 3 + 1] * Jv[3 + c] + H[r * 3 + 2] * Jv[6 + c];
        A[r * 6 + 3 + c] = H[r * 3 + c];
      }
  }
}

/* x_ij, for every reftype (the gateway passes both a_j and b_i). */
SBAEUC_EXPORT void sbaeuc_proj(int j, int i, double *aj, double *bi, double *xij, double **adata) {
  (void)i;
  euclidean(j, aj, bi, adata, xij, NULL, NULL);
}

/* 'motstr': A_ij and B_ij. */
SBAEUC_EXPORT void sbaeuc_projac(int j, int i, double *aj, double *bi, double *Aij, double *Bij,
                                 double **adata) {
  (void)i;
  euclidean(j, aj, bi, adata, NULL, Aij, Bij);
}

/* 'mot': A_ij only. */
SBAEUC_EXPORT void sbaeuc_projac_mot(int j, int i, double *aj, double *bi, double *Aij,
                                     double **adata) {
  (void)i;
  euclidean(j, aj, bi, adata, NULL, Aij, NULL);
}

/* 'str': B_ij only. */
SBAEUC_EXPORT void sbaeuc_projac_str(int j, int i, double *aj, double *bi, double *Bij,
                                     double **adata) {
  (void)i;
  euclidean(j, aj, bi, adata, NULL, NULL, Bij);
}
