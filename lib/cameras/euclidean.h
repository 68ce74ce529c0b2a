/* SPDX-License-Identifier: BSD-3-Clause */
// The Euclidean camera model of eucsbademo (docs/formats.md, "The camera model") and the sba
// callbacks built on it.
//
// A camera is a quaternion rotation, a translation and the intrinsics K = [fu s u0; 0 fu*ar v0;
// 0 0 1], optionally with Bouguet's distortion. The rotation is optimized through a local
// parametrization: camera j keeps its input rotation q0_j, and the optimizer sees only the
// vector part v of a small correction qs = (sqrt(1 - |v|^2), v), so that q = qs * q0_j. This
// keeps the rotation a unit quaternion without a constraint and starts every camera at v = 0,
// far from the parametrization's singularity at |v| = 1.
//
// Camera parameter vectors a_j (cnp values):
//   FixedIntrinsics               (v1 v2 v3  t1 t2 t3)                               cnp 6
//   VaryingIntrinsics             (fu u0 v0 ar s  v1 v2 v3  t1 t2 t3)                cnp 11
//   VaryingIntrinsicsDistortion   (fu u0 v0 ar s  kc0..kc4  v1 v2 v3  t1 t2 t3)      cnp 16
// Point parameters b_i = (X Y Z), pnp 3; projections (u v) in pixels, mnp 2.
#ifndef SBA_LIB_CAMERAS_EUCLIDEAN_H
#define SBA_LIB_CAMERAS_EUCLIDEAN_H

#include <array>
#include <vector>

#include "sba.h"

namespace sbacameras::euclidean {

enum class CameraKind {
  FixedIntrinsics,             // one K for all cameras, from the calibration file
  VaryingIntrinsics,           // per-camera K, optimized
  VaryingIntrinsicsDistortion  // per-camera K and distortion, optimized
};

// What the optimizer's parameter vector p holds, as in sba's three driver families.
enum class Refinement {
  MotionStructure,  // p = (a_1..a_m, b_1..b_n)
  Motion,           // p = (a_1..a_m); the points are fixed data of the model
  Structure         // p = (b_1..b_n); the cameras are fixed data of the model
};

constexpr int kPointParams = 3;        // pnp
constexpr int kMeasurementParams = 2;  // mnp
constexpr int kIntrinsicParams = 5;    // fu u0 v0 ar s
constexpr int kDistortionParams = 5;   // kc0..kc4

// cnp of a camera kind: 6, 11 or 16.
int camera_params(CameraKind kind);

// Scalar part first: q = w + x i + y j + z k.
struct Quaternion {
  double w = 1, x = 0, y = 0, z = 0;
};

// Hamilton product a * b (rotating by a * b applies b first, then a).
Quaternion multiply(const Quaternion &a, const Quaternion &b);
// q scaled to unit norm and negated if needed so that w >= 0 (q and -q are the same rotation),
// for a q of any nonzero size (components near 1e308 or 1e-300 included). The zero quaternion
// has no rotation to normalize; the readers refuse it before it gets here.
Quaternion normalized_rotation(const Quaternion &q);
// R (row-major 3x3) with R X = q X q^* for a unit q.
void rotation_matrix(const Quaternion &q, double R[9]);
// The unit quaternion (w >= 0) of a rotation matrix R (row-major), rotation_matrix's inverse.
// The largest of 4w, 4x, 4y, 4z is the pivot, for accuracy. No product is added to another, so
// no compiler fuses one (sbagen's scenes must be the same on every machine).
Quaternion quaternion_of(const double R[9]);

// K = [fu s u0; 0 fu*ar v0; 0 0 1].
struct Intrinsics {
  double fu = 1, u0 = 0, v0 = 0, ar = 1, s = 0;
};

// A camera as the files describe it.
struct Camera {
  Intrinsics k;
  std::array<double, kDistortionParams> kc{};  // Bouguet, zero-based: kc4 is the r^6 term
  Quaternion q;                                // world to camera: X_c = R(q) X + t
  std::array<double, 3> t{};
};

// The model's fixed data: what the callbacks receive as adata. It is immutable once built, so
// the callbacks keep no state of their own and any number of them may run at once on it.
class CameraModel {
 public:
  // cameras: the initial cameras (quaternions of any nonzero norm and sign; for
  // FixedIntrinsics each camera's k is the shared calibration). points: 3 per point, the
  // initial structure. nccalib: trailing intrinsics of (fu u0 v0 ar s) held at their initial
  // values (0..5); ncdist: trailing distortion terms of (kc0..kc4) held likewise (0..5).
  // A held value is read from the initial camera whatever p holds, so besides its zero
  // analytic Jacobian column it is also a constant for finite differences: the
  // finite-difference Jacobian, the Jacobian check (itmax 0) and the simple drivers all see
  // the same model as the analytic Jacobian.
  // Throws std::invalid_argument for nccalib or ncdist outside 0..5, a zero quaternion or a
  // point vector whose size is not a multiple of 3.
  CameraModel(CameraKind kind, const std::vector<Camera> &cameras, std::vector<double> points,
              int nccalib = 2, int ncdist = 3);

  CameraKind kind() const { return kind_; }
  int cnp() const { return cnp_; }
  int ncameras() const { return static_cast<int>(cameras0_.size()); }
  int npoints() const { return static_cast<int>(points0_.size() / kPointParams); }
  int nccalib() const { return nccalib_; }
  int ncdist() const { return ncdist_; }

  // The initial parameters: m*cnp camera values with v = 0, and the n*3 point coordinates.
  // Motion-only refinement projects the initial points, structure-only the initial cameras.
  const std::vector<double> &initial_camera_params() const { return cams0_; }
  const std::vector<double> &initial_points() const { return points0_; }
  const double *initial_camera(int j) const { return cams0_.data() + j * cnp_; }
  const double *initial_point(int i) const { return points0_.data() + i * kPointParams; }
  // The input camera j, its rotation q0_j scaled to unit norm with w >= 0.
  const Camera &input_camera(int j) const { return cameras0_[j]; }

  // Camera j in file form from its parameters a (cnp values): held intrinsics and distortion
  // terms at their initial values, rotation q = qs(v) * q0_j with unit norm and w >= 0.
  Camera camera(int j, const double *a) const;

  // x = the pixel projection of point b in camera j with parameters a.
  void project(int j, const double *a, const double *b, double x[kMeasurementParams]) const;
  // The projection and its derivatives: A = dx/da (2 x cnp), B = dx/db (2 x 3), row-major.
  // Any of x, A, B may be null. Held intrinsics/distortion terms get zero columns in A.
  // Bit-identical to the sba callbacks below (expert and simple alike).
  void project_jacobian(int j, const double *a, const double *b, double *x, double *A,
                        double *B) const;
  // The same, for a caller that evaluates one projection at a time (the benchmark's Ceres cost
  // function): the whole-vector callbacks derive the rotation through a per-camera tensor that
  // pays off over a camera's many points; this takes the derivative at the one point instead,
  // which is cheaper there. Equal to project_jacobian up to rounding.
  void project_jacobian_at_point(int j, const double *a, const double *b, double *x, double *A,
                                 double *B) const;

 private:
  template <CameraKind K>
  friend struct Kernel;

  CameraKind kind_;
  int cnp_;
  int nccalib_, ncdist_;
  std::vector<Camera> cameras0_; // the input cameras, q0_j unit with w >= 0
  std::vector<double> R0_;       // R(q0_j), 9 per camera: applied before the correction qs
  std::vector<double> cams0_;    // m*cnp initial camera parameters
  std::vector<double> points0_;  // n*3 initial points
};

// The pointer the drivers pass back to the callbacks. sba's adata is a non-const void*, but
// the callbacks only ever read through it.
inline void *as_adata(const CameraModel &model) {
  return const_cast<void *>(static_cast<const void *>(&model));
}

// ---- callbacks, selected by camera kind (adata must be a CameraModel) ----

using ExpertFn = void (*)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs,
                          double *out, void *adata);

// func writes hx (2 per visible projection, in the measurement order idxij->val gives);
// fjac writes the Jacobian blocks of each projection at that ordinal: A_ij then B_ij for
// motion+structure, A_ij alone for motion, B_ij alone for structure.
struct ExpertCallbacks {
  ExpertFn func;
  ExpertFn fjac;
};
ExpertCallbacks expert_callbacks(CameraKind kind, Refinement refinement);

// Per-projection callbacks of the simple drivers.
struct MotStrCallbacks {
  void (*proj)(int j, int i, double *aj, double *bi, double *xij, void *adata);
  void (*projac)(int j, int i, double *aj, double *bi, double *Aij, double *Bij, void *adata);
};
struct MotCallbacks {
  void (*proj)(int j, int i, double *aj, double *xij, void *adata);
  void (*projac)(int j, int i, double *aj, double *Aij, void *adata);
};
struct StrCallbacks {
  void (*proj)(int j, int i, double *bi, double *xij, void *adata);
  void (*projac)(int j, int i, double *bi, double *Bij, void *adata);
};
MotStrCallbacks motstr_callbacks(CameraKind kind);
MotCallbacks mot_callbacks(CameraKind kind);
StrCallbacks str_callbacks(CameraKind kind);

}  // namespace sbacameras::euclidean

#endif  // SBA_LIB_CAMERAS_EUCLIDEAN_H
