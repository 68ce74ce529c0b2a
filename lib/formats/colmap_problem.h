/* SPDX-License-Identifier: BSD-3-Clause */
// The one COLMAP problem: a COLMAP model and COLMAP's bundle adjustment options in, what
// sba_motstr_levmar_x_ext needs out, and the refined values written back into a model by id.
// Every front end (sbarefine, pysba) builds it, hands its arrays to the solve, and applies the
// result; none of them knows how a model maps onto sba (docs/architecture.md, "The COLMAP
// problem").
//
// Every image that sees a point is one sba camera, every 3D point one sba point. The camera
// model is one of COLMAP's own (cameras/colmap_camera.h):
// - an image with a pose of its own (a model without rigs and frames, or one whose frames hold
//   one image each and whose frames' poses are all refined), a_j = (v t params padding): its
//   pose, and a copy of the parameters of its COLMAP camera that are refined, in COLMAP's order
//   (one that is held takes no column);
// - otherwise an image of a rig, a_j = (frame pose | sensor pose | params padding), as COLMAP
//   4 refines it.
// Either way sba_ext_options::cam_param_group shares what COLMAP refines once: a COLMAP
// camera's parameters among its images, and in a rig a frame's pose among its images and a
// camera's pose in its rig among the frames (a rig's reference camera has the identity there,
// held). cam_fixed holds the padding and EQUIRECTANGULAR's size (w h) always, and what
// COLMAP's options and constants hold (Options).
#ifndef SBA_LIB_FORMATS_COLMAP_PROBLEM_H
#define SBA_LIB_FORMATS_COLMAP_PROBLEM_H

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "cameras/colmap_camera.h"
#include "formats/colmap_covariance.h"
#include "formats/colmap_io.h"
#include "formats/colmap_priors.h"
#include "formats/colmap_sba.h"
#include "formats/eucsba_io.h"
#include "sba.h"
#include "sba_ext.h"

namespace sbaformats::colmap {

// COLMAP's bundle adjuster's defaults for what the options of sba do not name: Ceres's
// max_num_iterations and function_tolerance.
constexpr int kDefaultItmax = 100;

// The strategy whose eps4 is COLMAP's function_tolerance.
constexpr const char *kColmapStrategy = "trust-region";

// COLMAP 4's gradient_tolerance (its BundleAdjustmentOptions set Ceres's to 1e-4; COLMAP 3.x's
// is 0).
constexpr double kColmapGradientTolerance = 1e-4;

// COLMAP's stopping rule on sba's options. COLMAP's bundle adjuster is Ceres's
// Levenberg-Marquardt, which stops at function_tolerance, a relative change of the cost: the
// trust-region strategy's eps4 (sba's eps4 is a relative reduction of the RMS error instead).
// function_tolerance < 0 means not given: then COLMAP's default, 0, unless a strategy or an
// eps4 is given (strategy_given, *eps4 not 0), which keep sba's tests. A tolerance sets *eps4
// to it, at least 4 ulp (a change rounding can make, so that a tolerance of 0 runs until a step
// no longer changes the cost beyond rounding), and returns true: the strategy, unless given, is
// then kColmapStrategy. False, *eps4 unchanged, when the rule leaves sba's tests.
// Ceres also stops when the largest entry of the gradient is at most gradient_tolerance: sba's
// stop 1, ||J^T e||_inf <= eps1. gradient_tolerance >= 0 sets *eps1 to it; not given (< 0), the
// rule sets COLMAP 4's kColmapGradientTolerance when it applies and *eps1 is sba's default,
// SBA_STOP_THRESH (an eps1 given is kept).
bool colmap_stop_rule(double function_tolerance, double gradient_tolerance, bool strategy_given, double *eps1,
                      double *eps4);

// What the solve holds beyond the parameters' own flags: COLMAP's options and constants, and
// sba's mcon (the first mcon sba cameras held; a COLMAP camera one of them uses has its
// parameters held in all its images, so that what is written back is one calibration) and
// ncon (the first ncon points).
// refine_points is COLMAP's refine_points3D (every point held without it); selection and gauge
// are its BundleAdjustmentConfig's.
struct Options {
  RefineIntrinsics intrinsics;
  RefinePoses poses;
  Constants constants;
  int mcon = 0, ncon = 0;
  bool refine_points = true;
  Selection selection;
  Gauge gauge = Gauge::None;
};

class Problem {
 public:
  // What the reports print of a problem.
  struct Counts {
    int shared_cameras = 0;   // COLMAP cameras refined once for several images
    int held_poses = 0;       // images whose pose is held, whether they see points or not
    int unseen_moved = 0;     // images that see no point but move with a refined frame or rig
    int frames = 0, held_frames = 0;    // rigged: the frames of the sba cameras, those held
    int sensors = 0, held_sensors = 0;  // rigged: their cameras that are not a rig's reference
    int held_intrinsics = 0;  // COLMAP cameras of the sba cameras with constant intrinsics
    // How the gauge is fixed: the options' gauge, or ThreePoints where TwoCamsFromWorld finds no
    // two images to fix it with (COLMAP falls back so too).
    Gauge gauge = Gauge::None;
  };

  // The problem of a model check_model accepted. False with "NAME: why" for a model that has
  // no problem (no images or no points, a camera model the camera models refuse). An image that
  // sees no point has no sba camera (nothing places it): it is held out of the problem; apply
  // leaves it as it was, or, in a rig, at its place in its frame.
  //
  // Without rigs and frames, or with frames of one image each and poses.rig_from_world without
  // poses.constant_rig_from_world_rotation, each image's pose is its own 6 parameters, held for
  // a held image (constants.poses), without poses.rig_from_world for every image, its rotation's
  // 3 held with poses.constant_rig_from_world_rotation; poses.sensor_from_rig changes nothing
  // (a frame of one image, free, takes up any change of its camera's pose in the rig).
  // Otherwise (rigged), a frame's pose is held in all its images without poses.rig_from_world,
  // or when one of its images is held (one that sees no point included) or below mcon; its
  // rotation with poses.constant_rig_from_world_rotation; a camera's pose in its rig in all its
  // images without poses.sensor_from_rig, with constants.sensor_from_rig, or when one of its
  // images is held or below mcon: holding an image's pose holds both parts of it, so that it
  // comes back as it was read.
  // Constant intrinsics are held as mcon holds a camera's (in all its images, shared by none);
  // constant points, and the first ncon points, are put first in the problem's points
  // (held_points counts them; without constant points it is ncon, and the order the file's).
  static bool build(const Model &model, const Options &options, const std::string &name, Problem *out,
                    std::string *error);

  Problem();
  Problem(Problem &&) noexcept;
  Problem &operator=(Problem &&) noexcept;
  ~Problem();

  // ---- what the solve takes ----
  int ncameras() const { return static_cast<int>(images_.size()); }
  int npoints() const { return points_.npoints(); }
  int cnp() const { return cnp_; }
  // p0: m cnp-vectors, then n points.
  const std::vector<double> &initial_params() const { return p0_; }
  // The projections, sba's visibility as pairs (by point, cameras ascending), and their
  // measurements.
  const eucsba::PointSet &points() const { return points_; }
  // The expert callbacks and their adata (a camera model of colmap_camera.h, immutable: the
  // callbacks may run on any number of threads at once).
  using Callback = void (*)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *out,
                            void *adata);
  Callback func() const;
  Callback fjac() const;
  void *adata() const;
  // m*cnp flags (sba_ext_options::cam_fixed with cam_fixed_per_camera) and group numbers
  // (cam_param_group).
  const std::vector<char> &cam_fixed() const { return cam_fixed_; }
  const std::vector<int> &cam_param_group() const { return cam_param_group_; }
  // The points held at the start (sba's ncon): the options' ncon and the constant points.
  int held_points() const { return held_points_; }
  // The cameras held at the start (sba's mcon).
  int mcon() const { return mcon_; }

  // ---- what the reports print ----
  // Whether the images are images of rigs (the rig camera model).
  bool rigged() const { return rigged_; }
  const Counts &counts() const { return counts_; }
  // Each sba camera's image, an index into the model's images.
  const std::vector<int> &images() const { return images_; }
  // Point i's projection in sba camera j at the parameters p (m*cnp + 3n values), the formula's
  // pixels; false where COLMAP's projection refuses the point (colmap_camera.h's `refused`),
  // whose cost the solve takes as zero.
  bool project(const double *p, int j, int i, double x[2]) const;
  // project(), for a caller that projects many observations in turn (one thread at a time): each
  // camera set up once while its parameters stay as they were.
  std::function<bool(const double *p, int j, int i, double x[2])> cached_project() const;
  // Each sba camera at the parameters p as one camera: its model, parameters and pose
  // (composed from its frame's and its camera's in a rig).
  std::vector<sbacameras::colmap_camera::Camera> cameras(const double *p) const;
  // Why the solve of the model the problem was built of cannot start, empty when it can: the
  // first observation, in the problem's order, whose squared reprojection error at the start
  // is not finite (a parameter that overflows the projection, as OPENCV's k1 = 1e200 does),
  // named by its image, that image's camera and the point: "NAME: image 13 (a.png), camera 101
  // (OPENCV): point 1007 projects to (1.2e+202, 3.4e+201) px, where its squared reprojection
  // error is not finite".
  std::string nonfinite_error(const Model &model, const std::string &name) const;

  // Writes the estimate p (m cnp-vectors, then n points) into model, a model with the ids of
  // the one the problem was built of (that model, or a copy): by camera, image, frame, rig and
  // point id, never by position. What is refined: the poses of the sba cameras from mcon on
  // that are not held (an image's own; in a rig, its frame's and its camera's pose in the rig;
  // in a model whose frames hold one image each, its frame's, so that the frame composes to
  // the refined pose, which the image's q and t then hold, as the images file will), each COLMAP
  // camera's parameters that are not held, the points from held_points on and (with errors)
  // their ERROR, the mean reprojection error in pixels (an observation COLMAP's projection
  // refuses counts the root of the largest double there, as in COLMAP). A held rotation or
  // translation, and everything else, keeps its bits. Without errors the points keep theirs,
  // as COLMAP's adjusters leave them, and no observation is projected.
  void apply(const double *p, Model *model, bool errors = true) const;

  // The covariance at the estimate p (m cnp-vectors, then n points) in COLMAP's convention
  // (colmap_covariance.h), of the model the problem was built of (its images' names): the
  // library's sba_motstr_covariance_x_vis over the problem, with ext's options (threads, loss,
  // log sink, cancel; the problem's held and shared parameters replace ext's), with `options`.
  // False when the library refuses, said through ext's sink.
  bool covariance(const Model &model, const double *p, const sba_ext_options &ext, const CovarianceOptions &options,
                  Covariances *out) const;

  // ---- what the priors take ----
  // The projection centre of sba camera j at its parameters a (cnp values): the image's own,
  // through its camera's pose in its rig in a rig. J, when not null, gets dc/da (3 x cnp,
  // row-major), by central differences over the pose's parameters (the rest do not move it).
  void centre(int j, const double *a, double c[3], double *J) const;
  // Sba camera j's IMAGE_ID, and problem point i's POINT3D_ID.
  std::uint32_t image_id(int j) const { return ids_[static_cast<std::size_t>(j)].image; }
  std::uint64_t point_id(int i) const { return point_ids_[static_cast<std::size_t>(i)]; }
  // The sba camera whose parameter vector carries COLMAP camera camera_id's parameters (the
  // first image of it from mcon on), and the position of its parameter k there, -1 where it
  // carries no such parameter (one held takes no column); false when no sba camera from mcon on
  // uses the camera.
  bool camera_parameter(std::uint32_t camera_id, int k, int *j, int *column) const;
  // Whether parameter c of sba camera j is held; c -1 (camera_parameter's) is.
  bool held(int j, int c) const {
    return c < 0 ||
           cam_fixed_[static_cast<std::size_t>(j) * static_cast<std::size_t>(cnp_) + static_cast<std::size_t>(c)] != 0;
  }

 private:
  struct Builder;
  struct Index;
  // Each sba camera's record, by id.
  struct CameraIds {
    std::uint32_t image = 0, camera = 0, frame = 0, rig = 0;
    bool reference = true;      // the rig's reference sensor (or no rigs)
    bool writes_params = true;  // the first sba camera of its COLMAP camera
  };
  template <typename F>
  decltype(auto) with_model(F f) const;
  void write_image(int j, const double *a, const Index &index) const;
  void write_rig_image(int j, const double *a, const Index &index,
                       std::unordered_map<std::uint32_t, char> *frames_done) const;
  void write_points(const double *p, const Index &index, bool errors) const;
  // covariance's blocks of the poses and of the COLMAP cameras from the sba cameras' blocks
  // camcov (m of cnp x cnp, unscaled).
  void pose_covariances(const Model &model, const double *p, const double *camcov, Covariances *out) const;
  void camera_covariances(const double *camcov, Covariances *out) const;

  std::vector<int> images_;
  std::vector<CameraIds> ids_;
  std::vector<std::uint64_t> point_ids_;  // problem point k's POINT3D_ID
  eucsba::PointSet points_;
  int cnp_ = 0, mcon_ = 0, held_points_ = 0;
  bool rigged_ = false;
  bool has_rigs_ = false;
  std::vector<char> cam_fixed_;
  std::vector<int> cam_param_group_;
  std::vector<double> p0_;
  Counts counts_;
  std::unique_ptr<sbacameras::colmap_camera::CameraModel> image_model_;
  std::unique_ptr<sbacameras::colmap_camera::RigCameraModel> rig_model_;
};

// The priors of a problem as the library takes them (sba_ext_options' prior fields), and the
// values they point to. Position priors are priors on the sba cameras' projection centres
// (Problem::centre), COLMAP's pose priors; point priors are on the problem's points (ground
// control points); intrinsics priors are linear priors on the sba camera that carries the
// COLMAP camera's parameters, so that a camera shared by its images counts once. The problem
// must outlive them, at the same address (the callbacks point to it).
class ProblemPriors {
 public:
  ProblemPriors() = default;
  // The library's structs point into the vectors below.
  ProblemPriors(const ProblemPriors &) = delete;
  ProblemPriors &operator=(const ProblemPriors &) = delete;
  // False with "WHERE: why" for a prior the problem cannot take: a point that is held, an
  // intrinsic parameter that is held or of a camera no refined image uses. A position prior
  // of an image whose pose is held entirely (or below mcon) is left out: it is a constant.
  bool build(const Problem &problem, const std::vector<PosePrior> &poses, const PosePriorOptions &options,
             const std::vector<PointPrior> &points, const std::vector<IntrinsicPrior> &intrinsics,
             std::string *error);
  // ext's prior fields pointed at these priors (none when there are none).
  void attach(sba_ext_options *ext) const;
  std::size_t size() const { return camera_.size() + linear_.size() + point_.size(); }
  std::size_t positions() const { return camera_.size(); }

 private:
  struct Position {
    const Problem *problem;
    int j;
    std::array<double, 3> mean;
    std::array<double, 9> covariance;
  };
  struct Linear {
    int j, param;
    double mean, sigma;
  };
  struct Point {
    int i;
    std::array<double, 3> mean;
    std::array<double, 9> covariance;
  };
  // The library's structs over positions_, linears_ and points_.
  void make_structs(double loss_scale);
  static void residual(int j, const double *aj, double *r, void *data);
  static void jacobian(int j, const double *aj, double *jac, void *data);

  std::vector<Position> positions_;
  std::vector<Linear> linears_;
  std::vector<Point> points_;
  std::string loss_;
  std::vector<sba_camera_prior> camera_;
  std::vector<sba_camera_linear_prior> linear_;
  std::vector<sba_point_prior> point_;
};

}  // namespace sbaformats::colmap

#endif  // SBA_LIB_FORMATS_COLMAP_PROBLEM_H
