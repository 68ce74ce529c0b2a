/* SPDX-License-Identifier: BSD-3-Clause */
// Priors of a COLMAP model (docs/priors.md, "sbarefine"): GPS positions of images as COLMAP 4
// keeps them (its database's pose_priors table, or a text file), ground control points and
// intrinsics, read and checked here; and what COLMAP's pose-prior bundle adjustment does with
// positions before the solve: WGS84 to a local east-north-up frame, a missing covariance
// replaced by a fallback, the model moved onto the priors by a robust similarity. The residuals
// themselves are the library's priors (sba_ext.h), built by colmap::Problem.
#ifndef SBA_LIB_FORMATS_COLMAP_PRIORS_H
#define SBA_LIB_FORMATS_COLMAP_PRIORS_H

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "formats/colmap_io.h"

namespace sbaformats::colmap {

// COLMAP's PosePrior::CoordinateSystem, by the values of its database.
enum class PriorSystem : int { Undefined = -1, Wgs84 = 0, Cartesian = 1 };

// A position prior of one image: where its projection centre is, and how well that is known.
// A WGS84 position is latitude and longitude in degrees and altitude in metres.
struct PosePrior {
  std::uint32_t image_id = 0;
  std::array<double, 3> position{};
  std::array<double, 9> covariance{};  // row-major, when has_covariance
  bool has_covariance = false;
  PriorSystem system = PriorSystem::Undefined;
  std::string where;  // names it in messages: "DB: pose prior 4 (image 7)", "FILE:12"
};

// The pose_priors table of COLMAP's database at path: COLMAP 4's layout (a prior per data
// item: those of cameras, whose data is an image), or 3.x's (a prior per image_id), whichever
// the table has. A position of 3 doubles is required; a covariance of 9 doubles, or NULL
// (none); the gravity of COLMAP 4 is not read. Rows in pose_prior_id (image_id) order. False
// with "PATH: why" when the file is not a database, has no such table, or a row's blob has
// another size than its field's.
bool read_pose_priors_database(const std::string &path, std::vector<PosePrior> *out, std::string *error);

// A text file of position priors, one a line (docs/priors.md):
//   NAME X Y Z [C11 C12 C13 C21 C22 C23 C31 C32 C33] [CARTESIAN|WGS84]
// The covariance row-major; '#' starts a comment line. A NAME that no image of model has is
// counted in *unknown and left out (the priors of a whole flight, of which the model holds the
// images it registered). False with "PATH:LINE: why".
bool read_pose_priors_text(const std::string &path, const Model &model, std::vector<PosePrior> *out,
                           int *unknown, std::string *error);
// The same of a file's text; name stands for the file in the messages.
bool parse_pose_priors_text(const std::string &text, const std::string &name, const Model &model,
                            std::vector<PosePrior> *out, int *unknown, std::string *error);

// COLMAP's use of the positions, as its pose-prior bundle adjustment takes them.
struct PosePriorOptions {
  // A prior without a covariance (none given, or one not finite) gets this standard deviation
  // in each axis (COLMAP's prior_position_fallback_stddev).
  double fallback_stddev = 1.0;
  // The robust loss on each prior's squared Mahalanobis distance: "" (COLMAP's TRIVIAL) or
  // "cauchy", and its scale (COLMAP's prior_position_loss_scale, sqrt of the 95% quantile of
  // chi-squared with 3 degrees of freedom).
  std::string loss;
  double loss_scale = 2.7954834829151074;
  // The similarity's inlier threshold, in the priors' units; 0: three times the priors' RMS
  // standard deviation.
  double alignment_max_error = 0;
};

// At least this many usable priors make COLMAP's adjustment a pose-prior one; with fewer it is
// its adjustment without priors.
constexpr int kMinPosePriors = 3;

// WGS84 positions to east-north-up metres around the first WGS84 prior (on the WGS84
// ellipsoid), as COLMAP's database cache converts them; they are then CARTESIAN. Covariances
// are kept as given.
void wgs84_to_enu(std::vector<PosePrior> *priors);

// The priors on images of model that see a point (an sba camera each), with their covariance
// set: given and finite, else the fallback. A prior of an image the model does not hold (one
// COLMAP did not register) or that sees no point is left out, and so is one without a position
// (all NaN: COLMAP's default). False with "WHERE: why" for an image given twice, a position
// that is not finite or a covariance that is not symmetric positive definite, or a fallback
// that is not finite and > 0.
bool usable_pose_priors(const Model &model, const std::vector<PosePrior> &priors, const PosePriorOptions &options,
                        std::vector<PosePrior> *out, std::string *error);

// X' = s R X + t.
struct Similarity {
  double s = 1;
  std::array<double, 9> R{1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::array<double, 3> t{};
};

// The similarity that takes src[k] to dst[k] (n >= 3 pairs), robustly (LO-RANSAC): the
// least-squares fit of all pairs and of random triples (a fixed seed: the same input gives the
// same result), each refitted on the pairs within max_error until those no longer change; the
// one with the most such pairs is kept, of equally many the closest. The fits are Horn's closed
// form with Umeyama's scale. *inliers: the pairs within max_error (0 when fewer than 3). False
// when the source points coincide.
bool robust_similarity(const std::vector<std::array<double, 3>> &src, const std::vector<std::array<double, 3>> &dst,
                       double max_error, Similarity *out, int *inliers);

// *x, the robust fit of src to dst, then moved to the least cost of the priors dst (with
// their covariances and loss: "" or "cauchy" of loss_scale) that a similarity of src reaches:
// the cost that the solve's position priors then add, and which the projections do not see
// change (they move with the whole model). Without it, the solve would spend its iterations
// turning and scaling the whole model by steps that its linear model of the projections holds
// back. False, and *x as it was, when no step lowers that cost.
bool least_cost_similarity(const std::vector<std::array<double, 3>> &src, const std::vector<std::array<double, 3>> &dst,
                           const std::vector<const std::array<double, 9> *> &covariances, const std::string &loss,
                           double loss_scale, Similarity *x);

// model moved by x: points X' = s R X + t, every pose with it (a frame's rig_from_world, or an
// image's own pose), each translation of a camera in its rig scaled by s.
void transform_model(const Similarity &x, Model *model);

// The projection centre of each image of model, by image index (image_poses).
std::vector<std::array<double, 3>> image_centres(const Model &model);

// A ground control point: a prior on a 3D point (docs/priors.md), in the model's frame.
struct PointPrior {
  std::uint64_t point_id = 0;
  std::array<double, 3> position{};
  std::array<double, 9> covariance{};  // row-major
  std::string where;                   // "FILE:LINE"
};

// A text file of point priors, one a line: POINT3D_ID X Y Z SIGMA, or POINT3D_ID X Y Z and the
// 9 values of a row-major covariance. False with "PATH:LINE: why": an unknown or repeated
// point, a value not finite, a SIGMA <= 0, a covariance not symmetric positive definite.
bool read_point_priors(const std::string &path, const Model &model, std::vector<PointPrior> *out,
                       std::string *error);
bool parse_point_priors(const std::string &text, const std::string &name, const Model &model,
                        std::vector<PointPrior> *out, std::string *error);

// What COLMAP 4's pose-prior bundle adjustment does before its solve, for every front end. The
// position priors `read` (unknown: how many more named images the model does not have; source:
// where they came from, for the words) go to east-north-up (wgs84_to_enu) and are checked
// (usable_pose_priors) into *poses. With at least kMinPosePriors of them, model is moved onto
// them by robust_similarity (when align: a front end that rewrites a model as read does not
// move it); with fewer, *poses is emptied: COLMAP's adjustment without priors. Without position
// priors, at least kMinPosePriors point priors (from points_source) move the model onto the
// control points likewise. *said: what was done, a line each, each starting with a newline.
// False with *error: priors that are not usable, or a similarity that would take the model
// beyond double's range.
bool place_on_priors(std::vector<PosePrior> read, int unknown, const std::string &source,
                     const std::vector<PointPrior> &points, const std::string &points_source,
                     const PosePriorOptions &options, bool align, Model *model, std::vector<PosePrior> *poses,
                     std::string *said, std::string *error);

// A prior on one intrinsic parameter of a COLMAP camera, in all its images.
struct IntrinsicPrior {
  std::uint32_t camera_id = 0;
  int param = 0;  // index in COLMAP's parameter list of the camera's model
  double mean = 0, stddev = 1;
  std::string where;
};

// A text file of intrinsics priors, one a line: CAMERA_ID PARAM MEAN STDDEV, PARAM the
// parameter's 0-based index in COLMAP's list for the camera's model, or f, fx, fy, cx, cy. False
// with "PATH:LINE: why": an unknown camera or parameter, a parameter given twice, a value not
// finite, STDDEV <= 0.
bool read_intrinsic_priors(const std::string &path, const Model &model, std::vector<IntrinsicPrior> *out,
                           std::string *error);
bool parse_intrinsic_priors(const std::string &text, const std::string &name, const Model &model,
                            std::vector<IntrinsicPrior> *out, std::string *error);

}  // namespace sbaformats::colmap

#endif  // SBA_LIB_FORMATS_COLMAP_PRIORS_H
