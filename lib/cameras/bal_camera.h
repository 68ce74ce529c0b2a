/* SPDX-License-Identifier: BSD-3-Clause */
// The BAL camera model and the sba callbacks built on it.
//
// Camera parameters a = (w1 w2 w3  t1 t2 t3  f k1 k2), cnp 9; point b = (X Y Z), pnp 3;
// measurement (x y) in pixels, mnp 2:
//   Q = R(w) X + t         R(w): the rotation by |w| about w/|w| (Rodrigues)
//   p = -(Q1/Q3, Q2/Q3)    the camera looks down its -z axis
//   r2 = |p|^2,  d = 1 + k1 r2 + k2 r2^2
//   x = f d p
// sba minimises ||x_obs - x(a, b)||^2, so the callbacks return the predicted pixels.
//
// The Jacobian is analytic. With s = |w|^2, alpha = sin|w|/|w| and beta = (1 - cos|w|)/s,
//   R(w) X = X + alpha (w x X) + beta w x (w x X),
// and both coefficients (and their derivatives in s) switch to their Taylor series for
// |w| < 1/4, where the closed forms lose digits to cancellation (and divide by zero at w = 0).
#ifndef SBA_LIB_CAMERAS_BAL_CAMERA_H
#define SBA_LIB_CAMERAS_BAL_CAMERA_H

struct sba_crsm;

namespace sbacameras::bal {

constexpr int kCameraParams = 9;       // cnp: Rodrigues w (3), t (3), f, k1, k2
constexpr int kPointParams = 3;        // pnp
constexpr int kMeasurementParams = 2;  // mnp

// R(w) as a row-major 3x3 matrix.
void rotation_matrix(const double w[3], double R[9]);

// The projection of point b by camera a; x receives 2 values.
void project(const double a[kCameraParams], const double b[kPointParams], double x[2]);

// The projection and its derivatives: A = dx/da (2x9) and B = dx/db (2x3), row-major. Any of
// x, A and B may be null.
void project_jacobian(const double a[kCameraParams], const double b[kPointParams], double *x,
                      double *A, double *B);

// What the expert callbacks need besides p: the parameter vector is m cameras (9 each)
// followed by the points (3 each). Immutable, so any number of callbacks may run on it at once.
struct CallbackData {
  int ncameras = 0;
};

// sba's expert callbacks for motion and structure (sba_motstr_levmar_x), adata a
// CallbackData*: func writes the predicted pixels of every visible projection at its
// measurement ordinal (idxij->val), fjac the blocks A_ij (2x9) then B_ij (2x3) at that ordinal.
void motstr_func(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata);
void motstr_fjac(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata);

// The same model's per-projection callbacks for the simple driver (sba_motstr_levmar's proj and
// projac): camera a_j and point b_i are handed over, adata is not read.
void motstr_proj(int j, int i, double *aj, double *bi, double *xij, void *adata);
void motstr_projac(int j, int i, double *aj, double *bi, double *Aij, double *Bij, void *adata);

}  // namespace sbacameras::bal

#endif  // SBA_LIB_CAMERAS_BAL_CAMERA_H
