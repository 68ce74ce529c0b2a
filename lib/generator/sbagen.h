/* SPDX-License-Identifier: BSD-3-Clause */
// sbagen: synthetic bundle adjustment problems with ground truth, for eucsbademo's camera
// model (../cameras/euclidean.h) and file formats (docs/formats.md).
//
// A scene is a set of true cameras and points, the tracks saying which cameras see which
// point, noisy measurements of the true projections (optionally with per-measurement 2x2
// covariances and gross outliers) and an initial estimate perturbed away from the truth. Every
// projection goes through sbacameras::euclidean::CameraModel::project, so the measurements follow exactly the
// model that eucsbademo refines.
//
// Determinism: one std::mt19937_64 stream (its output is fixed by the C++ standard) feeds
// every random choice through the integer and floating-point transforms in sbagen::Random, not
// through the <random> distributions, whose output differs between standard libraries. The
// integer choices (tracks, outlier selection) are therefore identical on every machine; the
// real values go through std::sqrt, std::log, std::sin and std::cos, which agree to the last
// bit wherever the C library rounds them correctly (glibc does) and otherwise differ by an
// ulp, far below the %.10e the files are written with.
//
// Size: memory is O(n + m + observations). The sparse tracks (track_begin / track_cameras)
// are always built; the dense n*m vmask that sba's C API takes is built only when n*m is at
// most Options::dense_vmask_limit (dense_vmask() builds it on demand).
#ifndef SBA_LIB_GENERATOR_SBAGEN_H
#define SBA_LIB_GENERATOR_SBAGEN_H

#include <cstddef>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "cameras/euclidean.h"
#include "formats/eucsba_io.h"

namespace sbagen {

// Portable random numbers from the raw 64-bit output of std::mt19937_64.
class Random {
 public:
  explicit Random(std::uint64_t seed) : engine_(seed) {}

  std::uint64_t bits() { return engine_(); }
  // Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(bits() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  // Uniform integer in [0, n), unbiased (rejection of the incomplete last block); n > 0.
  std::uint64_t below(std::uint64_t n);
  // Uniform integer in [lo, hi], lo <= hi.
  int between(int lo, int hi) { return lo + static_cast<int>(below(static_cast<std::uint64_t>(hi - lo) + 1)); }
  // Standard normal (Box-Muller; the second value of each pair is kept for the next call).
  double normal();

 private:
  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0;
};

enum class Trajectory {
  Orbit,  // cameras around a blob of points, all looking at its centre
  Path,   // cameras travelling forward along a gently curving road; each point is seen by a
          // run of consecutive cameras (the "long sequence")
  Photo   // a photo collection: clusters of cameras at many distances on the front half of a
          // landmark, all seeing most of it, with heavy-tailed track lengths, so that most
          // pairs of cameras share points (the reduced camera system is dense)
};

// Options with their defaults. Lengths are in scene units: the radius of the point cloud for
// Orbit (the cameras stand at the distance that fits that cloud in the image), the spacing
// of consecutive cameras for Path.
struct Options {
  // ---- cameras ----
  int cameras = 20;                                              // m >= 2
  Trajectory trajectory = Trajectory::Orbit;
  sbacameras::euclidean::CameraKind kind = sbacameras::euclidean::CameraKind::FixedIntrinsics;
  int image_width = 640;                                         // pixels, >= 16
  int image_height = 480;                                        // pixels, >= 16
  double focal = 800;         // fu of the true cameras (pixels); ar = 1, s = 0 throughout
  // Varying kinds: per-camera spread of the true fu and principal point around the shared
  // lens: fu_j = focal (1 + spread N), u0_j = u0 + spread * width/4 * N, v0_j likewise with
  // the height. The shared principal point is within 1% of the image centre.
  double intrinsics_spread = 0.01;
  // VaryingIntrinsicsDistortion: the lens has kc0 uniform in [-distortion, distortion] and
  // kc1 in [-distortion/4, distortion/4], each camera a little off that (5% of distortion),
  // tangential terms kc2, kc3 within 1% of distortion, kc4 = 0.
  double distortion = 0.1;
  double orbit_arc_deg = 360;  // Orbit: the arc the cameras are spread over (0 < arc <= 360)
  double path_yaw_deg = 0;     // Path: 0 looks ahead along the road, 90 to the side (|yaw| <= 90)
  double path_turn_deg = 10;   // Path: largest heading change of the road's gentle S-curve

  // ---- points ----
  int points = 1500;  // n >= 1
  int track_min = 2;  // each point is seen by track_min..track_max cameras (2 <= min <= max),
  int track_max = 10; // consecutive ones for Path; track_min <= cameras. Uniform lengths for
                      // Orbit and Path; for Photo a Pareto tail from track_min (most tracks
                      // short, a few very long), mean about 4 track_min when track_max allows

  // ---- measurements ----
  double noise = 0.5;        // pixel noise sigma (Gaussian); 0 gives exact projections
  // Per-measurement covariances: a random SPD 2x2 matrix whose principal standard deviations
  // are uniform in [noise/2, 2 noise] at a uniform angle; the noise is drawn from it. Needs
  // noise > 0. Written to the points file in the upper-triangular form.
  bool covariances = false;
  // Fraction of measurements replaced by gross outliers: round(outliers * projections) of
  // them, chosen uniformly, each uniform in the image and at least max(5, 10 sigma_max)
  // pixels from its true projection (sigma_max = noise, 2 noise with covariances; the
  // distance is capped at a quarter of the smaller image side). Flagged in Scene::outlier.
  // True projections keep 5 sigma_max (at least 1 pixel) inside the image border.
  double outliers = 0;

  // ---- initial estimate (standard deviations) ----
  double perturb_rotation = 0.01;     // radians, per axis of a small rotation applied to each camera
  double perturb_translation = 0.02;  // scene units, per component of each t
  double perturb_points = 0.02;       // scene units, per coordinate of each point
  // Varying kinds: fu, u0, v0 each scaled by (1 + perturb_intrinsics N); with distortion kc0 and
  // kc1 also shifted by perturb_intrinsics N. The terms eucsbademo holds by default (ar, s,
  // kc2..kc4) keep their true values.
  double perturb_intrinsics = 0.01;

  std::uint64_t seed = 1;

  // The dense vmask (n*m chars) is built only when n*m <= this; 0 never builds it.
  std::size_t dense_vmask_limit = std::size_t{1} << 26;

  // True if the options describe a problem that can be generated; otherwise false and a
  // one-line reason in *error (when error is not null).
  bool IsValid(std::string *error) const;
};

// A generated problem. Projection k (the measurement ordinal, point by point with cameras
// ascending, as sba's x and covx are laid out) is point i seen by camera track_cameras[k],
// for track_begin[i] <= k < track_begin[i + 1].
struct Scene {
  sbacameras::euclidean::CameraKind kind = sbacameras::euclidean::CameraKind::FixedIntrinsics;
  int image_width = 0, image_height = 0;
  double scene_scale = 1;  // the scene unit of the Options, in world units

  // Unit quaternions with w >= 0. For FixedIntrinsics every camera's k is the shared
  // calibration and kc is zero.
  std::vector<sbacameras::euclidean::Camera> true_cameras;
  std::vector<sbacameras::euclidean::Camera> initial_cameras;
  std::vector<double> true_points;  // 3 per point

  std::vector<std::size_t> track_begin;  // n + 1 offsets
  std::vector<int> track_cameras;        // one camera index per projection
  std::vector<double> true_x;            // 2 per projection: the exact projections of the truth

  // What sba's C API takes: xyz = the initial points, x = the measurements (noise and
  // outliers included), covx (4 per projection, row-major) when covariances were asked for,
  // vmask = the dense n*m visibility when n*m <= Options::dense_vmask_limit, else empty.
  sbaformats::eucsba::PointSet measurements;

  std::vector<char> outlier;  // 1 per projection: nonzero for a gross outlier

  int ncameras() const { return static_cast<int>(true_cameras.size()); }
  int npoints() const { return static_cast<int>(true_points.size() / 3); }
  std::size_t nprojections() const { return track_cameras.size(); }
  const std::vector<double> &initial_points() const { return measurements.xyz; }
  bool has_dense_vmask() const { return !measurements.vmask.empty(); }
  std::size_t noutliers() const;
};

// Builds a scene from the options. Returns false with a one-line reason in *error (when not
// null) for invalid options or when the points cannot be placed (e.g. tracks longer than the
// geometry allows). May throw std::bad_alloc.
bool generate(const Options &options, Scene *scene, std::string *error);

// The dense n*m visibility of a scene (vmask[i * m + j] = 1 iff camera j sees point i).
std::vector<char> dense_vmask(const Scene &scene);

// The files of a problem written by write_problem.
struct ProblemFiles {
  std::string cams, pts, calib, truth_cams, truth_pts, outliers;  // calib, outliers empty when not written
};
ProblemFiles problem_files(const std::string &prefix, const Scene &scene);

// Writes the problem under prefix:
//   PREFIX-cams.txt        initial cameras in eucsbademo's format of the scene's kind
//   PREFIX-pts.txt         initial points with their tracks (and covariances)
//   PREFIX-calib.txt       the shared K (FixedIntrinsics only)
//   PREFIX-truth-cams.txt  true cameras, same format
//   PREFIX-truth-pts.txt   true points with the exact projections of their tracks (and the
//                          same covariances): a noise-free problem with the same structure
//   PREFIX-outliers.txt    `point camera` of every gross outlier (only when there are some)
// The points files go through sbaformats::eucsba::write_points when the scene has its dense vmask and
// through write_points_sparse otherwise (the same text).
// False, with the file and why in *error, when a file cannot be written.
bool write_problem(const Scene &scene, const std::string &prefix, std::string *error);

// A points file in sbaformats::eucsba::write_points' format from the sparse tracks: coordinates xyz
// (3 per point), the projections x (2 per projection) and the scene's covariances.
bool write_points_sparse(const std::string &path, const Scene &scene, const std::vector<double> &xyz,
                         const std::vector<double> &x, std::string *error);

// The calibration file of eucsbademo: K = [fu s u0; 0 fu*ar v0; 0 0 1], three rows.
bool write_calibration(const std::string &path, const sbacameras::euclidean::Intrinsics &k, std::string *error);

const char *trajectory_name(Trajectory t);      // "orbit", "path", "photo"
// The trajectory of a name trajectory_name gives; false for any other name.
bool trajectory_from_name(const std::string &name, Trajectory *t);
const char *camera_kind_name(sbacameras::euclidean::CameraKind kind);  // "fixed", "varK", "varKD"

}  // namespace sbagen

#endif  // SBA_LIB_GENERATOR_SBAGEN_H
