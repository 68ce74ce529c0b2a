/* SPDX-License-Identifier: BSD-3-Clause */
// COLMAP's eighteen camera models (docs/formats.md, "COLMAP sparse models") with analytic
// derivatives, and the sba camera models built on them for sbarefine: one of an image with a
// pose of its own, one of an image of a rig (COLMAP 4's frames and rigs).
//
// Most models map a point X_c of the camera frame to pixels through u = X/Z, v = Y/Z, then the
// model's distortion (u, v) -> (u_d, v_d), then x = fx u_d + cx, y = fy v_d + cy (f for both
// where the model has one focal length). The parameters are COLMAP's, in COLMAP's order; the
// models with one focal length put it first (f cx cy ...), the others fx fy cx cy ...; what
// follows the principal point are the "extra" parameters (distortion). With r^2 = u^2 + v^2:
//   SIMPLE_PINHOLE, PINHOLE   u_d = u
//   SIMPLE_RADIAL k           u_d = u (1 + k r^2)
//   RADIAL k1 k2              u_d = u (1 + k1 r^2 + k2 r^4)
//   OPENCV k1 k2 p1 p2        u_d = u R + 2 p1 u v + p2 (r^2 + 2 u^2),
//                             v_d = v R + p1 (r^2 + 2 v^2) + 2 p2 u v,  R = 1 + k1 r^2 + k2 r^4
//   FULL_OPENCV k1 k2 p1 p2 k3 k4 k5 k6   as OPENCV with
//                             R = (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
//   OPENCV_FISHEYE k1..k4     u_d = u theta_d / r, theta = atan(r),
//                             theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
//   SIMPLE_RADIAL_FISHEYE k   the same with theta_d = theta (1 + k theta^2)
//   RADIAL_FISHEYE k1 k2      theta_d = theta (1 + k1 theta^2 + k2 theta^4)
//   SIMPLE_FISHEYE, FISHEYE   theta_d = theta (the equidistant projection)
//   FOV omega                 u_d = u atan(2 r tan(omega / 2)) / (omega r)  (omega -> 0: u_d = u)
//   THIN_PRISM_FISHEYE k1 k2 p1 p2 k3 k4 sx1 sy1: first the equidistant mapping
//                             (u_f, v_f) = (u, v) theta / r, then with t^2 = u_f^2 + v_f^2 and
//                             R = 1 + k1 t^2 + k2 t^4 + k3 t^6 + k4 t^8:
//                             u_d = u_f R + 2 p1 u_f v_f + p2 (t^2 + 2 u_f^2) + sx1 t^2,
//                             v_d = v_f R + p1 (t^2 + 2 v_f^2) + 2 p2 u_f v_f + sy1 t^2
//   RAD_TAN_THIN_PRISM_FISHEYE k0..k5 p0 p1 s0 s1 s2 s3: first (u_f, v_f) = (u, v) theta_d / r
//                             with theta_d = theta (1 + k0 theta^2 + ... + k5 theta^12), then
//                             with t^2 = u_f^2 + v_f^2 (p0 and p1 in the roles OPENCV gives p2, p1):
//                             u_d = u_f + p0 (t^2 + 2 u_f^2) + 2 p1 u_f v_f + s0 t^2 + s1 t^4,
//                             v_d = v_f + 2 p0 u_f v_f + p1 (t^2 + 2 v_f^2) + s2 t^2 + s3 t^4
// theta / r and the FOV factor are evaluated through atan(s)/s as a function of s^2, by its
// series near 0: the models are smooth at r = 0 (and FOV at omega = 0), and so are the values
// and derivatives here, with no division by r.
//
// Four models are functions of the point itself rather than of (u, v), as COLMAP evaluates
// them: they give the same pixels for X_c and s X_c for any s > 0, but a point behind the
// camera (Z < 0) is not mirrored onto one in front. With rho = X^2 + Y^2:
//   SIMPLE_DIVISION, DIVISION k   Fitzgibbon's division model, undistorted = distorted /
//                             (1 + k |distorted|^2), solved for the distorted point by the root
//                             that is the pinhole's at k = 0:
//                             u_d = 2 X / (Z + sqrt(Z^2 - 4 k rho)), v_d likewise with Y
//   EUCM alpha beta           the enhanced unified camera model (Khomenko et al.):
//                             u_d = X / (alpha d + (1 - alpha) Z), d = sqrt(beta rho + Z^2)
//   EQUIRECTANGULAR w h       a panorama w by h pixels: x = w/2 + w/(2 pi) atan2(X, Z),
//                             y = h/2 + h/pi atan2(Y, sqrt(X^2 + Z^2)). w and h are the
//                             panorama's size, not parameters of a lens: COLMAP never refines
//                             them.
// Where a formula has no value, the projection is not finite, as COLMAP's is: DIVISION with
// Z^2 < 4 k rho (k > 0: a ray farther off the axis than the model reaches). `project` checks
// neither that the point is in front of the camera nor EUCM's region of validity: the pixels
// are the formula's wherever it has a value, as COLMAP's projection without its cheirality
// check gives them. `refused` is that check: where COLMAP's projection gives no pixel, COLMAP
// 4's reprojection cost is zero, and so is the cost of the sba models below once they are given
// the measurements.
#ifndef SBA_LIB_CAMERAS_COLMAP_CAMERA_H
#define SBA_LIB_CAMERAS_COLMAP_CAMERA_H

#include <array>
#include <memory>
#include <vector>

#include "cameras/euclidean.h"
#include "sba.h"

namespace sbacameras::colmap_camera {

// COLMAP's model ids.
enum ModelId : int {
  kSimplePinhole = 0,
  kPinhole = 1,
  kSimpleRadial = 2,
  kRadial = 3,
  kOpenCV = 4,
  kOpenCVFisheye = 5,
  kFullOpenCV = 6,
  kFov = 7,
  kSimpleRadialFisheye = 8,
  kRadialFisheye = 9,
  kThinPrismFisheye = 10,
  kRadTanThinPrismFisheye = 11,
  kSimpleDivision = 12,
  kDivision = 13,
  kSimpleFisheye = 14,
  kFisheye = 15,
  kEucm = 16,
  kEquirectangular = 17
};
constexpr int kNumModels = 18;
constexpr int kMaxParams = 16;  // RAD_TAN_THIN_PRISM_FISHEYE

// COLMAP's table of its models, the one the programs, pysba and the file formats read: each
// row carries its id, so that a row out of the enum's order does not compile.
struct ModelInfo {
  ModelId id;
  const char *name;
  int params;
  int focals;  // f, or fx and fy, leading the parameters; 0 for EQUIRECTANGULAR's w h
};
inline constexpr ModelInfo kModels[] = {
    {kSimplePinhole, "SIMPLE_PINHOLE", 3, 1},
    {kPinhole, "PINHOLE", 4, 2},
    {kSimpleRadial, "SIMPLE_RADIAL", 4, 1},
    {kRadial, "RADIAL", 5, 1},
    {kOpenCV, "OPENCV", 8, 2},
    {kOpenCVFisheye, "OPENCV_FISHEYE", 8, 2},
    {kFullOpenCV, "FULL_OPENCV", 12, 2},
    {kFov, "FOV", 5, 2},
    {kSimpleRadialFisheye, "SIMPLE_RADIAL_FISHEYE", 4, 1},
    {kRadialFisheye, "RADIAL_FISHEYE", 5, 1},
    {kThinPrismFisheye, "THIN_PRISM_FISHEYE", 12, 2},
    {kRadTanThinPrismFisheye, "RAD_TAN_THIN_PRISM_FISHEYE", 16, 2},
    {kSimpleDivision, "SIMPLE_DIVISION", 4, 1},
    {kDivision, "DIVISION", 5, 2},
    {kSimpleFisheye, "SIMPLE_FISHEYE", 3, 1},
    {kFisheye, "FISHEYE", 4, 2},
    {kEucm, "EUCM", 6, 2},
    {kEquirectangular, "EQUIRECTANGULAR", 2, 0}};

// Whether row k of the table is model id k, and none has more parameters than kMaxParams.
constexpr bool table_is_by_id() {
  for (int k = 0; k < kNumModels; ++k)
    if (kModels[k].id != k || kModels[k].params > kMaxParams) return false;
  return true;
}
static_assert(sizeof kModels / sizeof kModels[0] == kNumModels, "one row per model id");
static_assert(table_is_by_id(), "kModels is indexed by ModelId");
constexpr int kPoseParams = 6;  // v1 v2 v3 t1 t2 t3
constexpr int kPointParams = 3;
constexpr int kMeasurementParams = 2;

// COLMAP's name of a model id, nullptr outside 0..17.
const char *model_name(int model);
// The number of parameters of a model id (0 outside 0..17).
int param_count(int model);
// 1 (f) or 2 (fx fy): the leading focal length parameters; the principal point follows them.
// 0 for EQUIRECTANGULAR, which has neither.
int focal_count(int model);

// The cnp of cameras whose largest parameter count is max_params: 6 + max_params, rounded up
// to the next size the library has fixed-size kernels for (9, 11, 16; src/kernels.h), for
// which a solve takes about half the time of the generic kernels'. The slots beyond the
// model's parameters are padding.
int camera_params(int max_params);

// What a parameter is, as COLMAP's refine_* options group them; Size is EQUIRECTANGULAR's w
// and h, which none of them refines.
enum class ParamKind { Focal, Principal, Extra, Size };
ParamKind param_kind(int model, int k);

// x = the pixels of the camera-frame point Xc through model `model` with parameters
// `params` (param_count(model) of them). Jp = dx/dparams (2 rows of param_count values,
// row-major), Jx = dx/dXc (2x3, row-major); either may be null. Xc[2] must not be 0 (but for
// EQUIRECTANGULAR, which needs X and Z not both 0, and the division models and EUCM, which
// need their denominators not 0).
void project(int model, const double *params, const double Xc[3], double x[2], double *Jp, double *Jx);

// Whether COLMAP's projection gives no pixel for the camera-frame point Xc: Xc[2] below the
// epsilon of doubles (a point behind the camera, or on its plane) for every model but three.
// The division models refuse only a ray their formula has no value for (Z^2 < 4 k rho), and
// EQUIRECTANGULAR refuses none.
bool refused(int model, const double *params, const double Xc[3]);

// A camera as sbarefine refines it: a COLMAP model and its parameters, and the pose
// X_c = R(q) X + t.
struct Camera {
  int model = kSimplePinhole;
  std::vector<double> params;
  euclidean::Quaternion q;
  std::array<double, 3> t{};
};

// What the two sba camera models below keep alike: cnp, every camera's initial parameter
// vector, the initial points and the held flags, and how a parameter vector is read through
// them.
class SbaCameraModel {
 public:
  int cnp() const { return cnp_; }
  int ncameras() const { return m_; }
  int npoints() const { return static_cast<int>(points0_.size() / kPointParams); }
  const std::vector<double> &initial_camera_params() const { return cams0_; }
  const std::vector<double> &initial_points() const { return points0_; }
  const double *initial_camera(int j) const { return cams0_.data() + static_cast<std::size_t>(j) * cnp_; }
  // Camera j's held flags (cnp), or null when nothing is held.
  const char *held(int j) const {
    return held_.empty() ? nullptr : held_.data() + static_cast<std::size_t>(j) * cnp_;
  }
  // Camera j's parameters as its model reads them, from its parameter vector a: the pose's
  // (first() values) and then its COLMAP model's parameters in COLMAP's order, a held
  // parameter at its initial value and one that a does not carry at its given value.
  void expanded(int j, const double *a, double *out) const;
  // The column of a_j that carries camera j's model parameter k (0 <= k < kMaxParams); -1
  // where a_j does not carry it (CameraModel's `kept`), or the model has no parameter k.
  int param_column(int j, int k) const {
    const int s = slot_[static_cast<std::size_t>(j) * kMaxParams + static_cast<std::size_t>(k)];
    return s < 0 ? -1 : first_ + s;
  }
  // Camera j's model parameters' columns after the pose's: param_column's less the pose's
  // count, or -1.
  const signed char *slots(int j) const { return slot_.data() + static_cast<std::size_t>(j) * kMaxParams; }
  // The measurements of the projections, 2 per ordinal (sba's x, in the order of idxij's
  // ordinals), or null (the default). With them, the callbacks cost a projection COLMAP refuses
  // (`refused`) nothing, as COLMAP 4's cost does: its hx is its measurement and its Jacobian is
  // zero. The caller sets them before the callbacks run, and keeps x alive and unchanged
  // while the model is used.
  void set_measurements(const double *x) { measurements_ = x; }
  const double *measurements() const { return measurements_; }

 protected:
  // Throws std::invalid_argument for points whose count is not a multiple of 3 or held flags
  // of another size than m*cnp; the initial parameters are m*cnp zeros for the caller to fill
  // (set_params the model's parameters, from column `first` on).
  SbaCameraModel(int m, int cnp, int first, std::vector<double> points, std::vector<char> held);
  double *initial_camera(int j) { return cams0_.data() + static_cast<std::size_t>(j) * cnp_; }
  // Camera j's model parameters as given, and those its parameter vector carries: `kept`
  // (ascending indices), or every one when kept is null; into its initial vector in that order.
  void set_params(int j, const std::vector<double> &params, const std::vector<int> *kept);

 private:
  int m_, cnp_, first_;
  std::vector<char> held_;           // m*cnp flags, or empty
  std::vector<double> cams0_;        // m*cnp initial camera parameters
  std::vector<double> params0_;      // m*kMaxParams: each camera's model parameters as given
  std::vector<signed char> slot_;    // m*kMaxParams: model parameter k at column first + slot, or -1
  std::vector<signed char> nparams_;  // each camera's model parameter count
  std::vector<double> points0_;      // n*3
  const double *measurements_ = nullptr;
};

// The largest number of model parameters that `kept` gives a camera (CameraModel).
int largest_kept(const std::vector<std::vector<int>> &kept);

// The sba camera model of a set of such cameras. Camera parameter vector a_j (cnp values):
//   (v1 v2 v3  t1 t2 t3  params of camera j's model (those kept)  zero padding)
// The rotation is euclidean.h's local parametrization: R(qs(v)) R(q0_j), v = 0 at the start.
// cnp = camera_params(the largest parameter count, or count kept, among the cameras), so that
// cameras of different models share one layout; the padding slots do not enter the projection
// (zero Jacobian columns) and the caller holds them (sba_ext_options::cam_fixed). The model is
// immutable once built: the callbacks keep no state and may run on any number of threads at
// once.
class CameraModel : public SbaCameraModel {
 public:
  // held: empty, or cnp flags per camera (camera j's at j*cnp, as sba_ext_options::cam_fixed
  // with cam_fixed_per_camera): a held parameter is read from the initial camera whatever p
  // holds, and its Jacobian column is zero, so that finite differences (the Jacobian check)
  // and a solve that does not hold it see the same model as one that does.
  // kept: empty, or per camera the indices (ascending) of the model parameters that a_j
  // carries, in that order after the pose; the others stay at their given values, as held ones
  // do, but take no column: a problem that holds the principal points, as COLMAP does by
  // default, has camera blocks two columns narrower (cnp = camera_params(the largest count
  // kept)), and every block operation of a solve is cheaper for it.
  // Throws std::invalid_argument for an unknown model id, a parameter count that is not the
  // model's, a zero quaternion, points whose count is not a multiple of 3, held flags of
  // another size than m*cnp, or kept lists that are not one per camera of ascending indices of
  // its model's parameters.
  CameraModel(const std::vector<Camera> &cameras, std::vector<double> points, std::vector<char> held = {},
              const std::vector<std::vector<int>> &kept = {});

  const Camera &input_camera(int j) const { return cameras0_[static_cast<std::size_t>(j)]; }
  // R(q0_j), row-major.
  const double *initial_rotation(int j) const { return R0_.data() + static_cast<std::size_t>(j) * 9; }

  // Camera j from its parameters a: the model's parameters, q = qs(v) q0_j (unit, w >= 0), t.
  Camera camera(int j, const double *a) const;

  // The projection of point b in camera j with parameters a, and A = dx/da (2 x cnp), B =
  // dx/db (2 x 3), row-major; any of x, A, B may be null. The numbers of the callbacks without
  // measurements, bit for bit: the formula's, where COLMAP refuses the point too. False where it
  // does. The callbacks run code compiled for each common model; this runs the code for any.
  bool project_jacobian(int j, const double *a, const double *b, double *x, double *A, double *B) const;
  bool project(int j, const double *a, const double *b, double x[2]) const {
    return project_jacobian(j, a, b, x, nullptr, nullptr);
  }

 private:
  std::vector<Camera> cameras0_;  // q0_j unit with w >= 0
  std::vector<double> R0_;        // R(q0_j), 9 per camera
};

inline void *as_adata(const CameraModel &model) {
  return const_cast<void *>(static_cast<const void *>(&model));
}

// The expert motion-and-structure callbacks (adata a CameraModel): func writes hx, 2 values
// per projection at the ordinal idxij->val gives; fjac writes A_ij (2 x cnp) then B_ij (2 x 3)
// at that ordinal. They walk the index by rows and write only their projections' slots, so
// they are safe with sba_ext_options::parallel_callbacks.
void motstr_func(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata);
void motstr_fjac(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata);

// COLMAP's tangent of a rotation, as its covariances are given: the increment delta of
// q = [cos|delta|, sin|delta| delta/|delta|] * q_hat, a rotation by 2|delta| applied on the left
// (Ceres's quaternion manifold), as a function of the local rotation parameters v of the
// models below (R = R(qs(v)) R0) at v_hat: J = d(delta)/dv, 3x3 row-major, so that a
// covariance C of v is J C J^T in COLMAP's tangent. v_hat must have |v_hat| < 1.
void rotation_tangent_jacobian(const double v_hat[3], double J[9]);

// ---- the images of camera rigs (COLMAP 4's rigs and frames) ----

constexpr int kRigPoseParams = 12;  // the frame's v t, then the sensor's v t

// An image of a rig as sbarefine refines it: a COLMAP model and its parameters, the pose of
// its frame (rig_from_world: X_r = R(q_frame) X + t_frame) and the pose of its camera in the
// rig (sensor_from_rig: X_c = R(q_sensor) X_r + t_sensor; the identity for the rig's
// reference camera).
struct RigImage {
  int model = kSimplePinhole;
  std::vector<double> params;
  euclidean::Quaternion q_frame;
  std::array<double, 3> t_frame{};
  euclidean::Quaternion q_sensor;
  std::array<double, 3> t_sensor{};
};

// The cnp of rig images whose largest parameter count is max_params: 12 + max_params, rounded
// up to 16 (the library's largest fixed-size kernel) when it is below.
int rig_camera_params(int max_params);

// The sba camera model of the images of rigs: every image is an sba camera whose parameter
// vector a_j (cnp values) is
//   (v_f t_f  v_s t_s  params of image j's COLMAP camera (those kept)  zero padding)
// with X_c = R_s (R_f X + t_f) + t_s, R_f = R(qs(v_f)) R(q_frame), R_s = R(qs(v_s)) R(q_sensor)
// in euclidean.h's local parametrization, v_f = v_s = 0 at the start. The images of one frame
// start from one frame pose and the images of one camera from one sensor pose, so that the
// caller can share these columns among them (sba_ext_options::cam_param_group): the frame's
// pose by frame, the sensor's by camera, the intrinsics by COLMAP camera. Held flags,
// padding and threads as CameraModel's.
class RigCameraModel : public SbaCameraModel {
 public:
  // kept as CameraModel's (cnp = rig_camera_params(the largest count kept)).
  // Throws std::invalid_argument as CameraModel's constructor does (a zero quaternion of
  // either pose included).
  RigCameraModel(const std::vector<RigImage> &images, std::vector<double> points, std::vector<char> held = {},
                 const std::vector<std::vector<int>> &kept = {});

  // Image j as given, both quaternions unit with w >= 0.
  const RigImage &input_image(int j) const { return images0_[static_cast<std::size_t>(j)]; }
  // R(q_frame) and R(q_sensor) of image j as given, row-major.
  const double *initial_frame_rotation(int j) const { return R0_.data() + static_cast<std::size_t>(j) * 18; }
  const double *initial_sensor_rotation(int j) const { return initial_frame_rotation(j) + 9; }

  // Image j from its parameters a: the model's parameters, q_frame = qs(v_f) q_frame0 and
  // q_sensor = qs(v_s) q_sensor0 (unit, w >= 0), the translations.
  RigImage image(int j, const double *a) const;
  // Image j as one camera: its parameters and its pose compose(sensor_from_rig, rig_from_world)
  // (rigid_pose.h), normalized.
  Camera camera(int j, const double *a) const;

  // As CameraModel's: x, A = dx/da (2 x cnp), B = dx/db (2 x 3), false where COLMAP refuses.
  bool project_jacobian(int j, const double *a, const double *b, double *x, double *A, double *B) const;
  bool project(int j, const double *a, const double *b, double x[2]) const {
    return project_jacobian(j, a, b, x, nullptr, nullptr);
  }

 private:
  std::vector<RigImage> images0_;  // quaternions unit with w >= 0
  std::vector<double> R0_;         // R(q_frame), R(q_sensor): 18 per image
};

inline void *as_adata(const RigCameraModel &model) {
  return const_cast<void *>(static_cast<const void *>(&model));
}

// project() of a CameraModel or RigCameraModel, each camera's frame (its rotation and what
// else does not depend on the point) kept from one projection to the next while the camera's
// parameters keep their bits: the same numbers, for reports that project every observation
// in turn. Not for concurrent use.
template <class Model>
class CachedProjection {
 public:
  explicit CachedProjection(const Model &model);
  ~CachedProjection();
  CachedProjection(const CachedProjection &) = delete;
  CachedProjection &operator=(const CachedProjection &) = delete;
  bool project(int j, const double *a, const double *b, double x[2]);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The expert callbacks of a RigCameraModel (adata), as motstr_func and motstr_fjac.
void rig_motstr_func(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata);
void rig_motstr_fjac(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata);

}  // namespace sbacameras::colmap_camera

#endif  // SBA_LIB_CAMERAS_COLMAP_CAMERA_H
