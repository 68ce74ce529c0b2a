/* SPDX-License-Identifier: BSD-3-Clause */
// What a COLMAP model's refinement is asked (COLMAP's bundle adjustment options and
// constants, and the lists that name them), and how the model maps onto eucsbademo's camera
// for other programs and tests. The problem itself, and the refined values written back, are
// colmap_problem.h's.
#ifndef SBA_LIB_FORMATS_COLMAP_SBA_H
#define SBA_LIB_FORMATS_COLMAP_SBA_H

#include <cstddef>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "cameras/colmap_camera.h"
#include "cameras/euclidean.h"
#include "formats/colmap_io.h"
#include "formats/eucsba_io.h"

namespace sbaformats::colmap {

// Which intrinsics are refined, as COLMAP's bundle adjuster names them: refine_focal_length,
// refine_principal_point and refine_extra_params (distortion here), with COLMAP's defaults:
// the focal length and the distortion refined, the principal point held.
struct RefineIntrinsics {
  bool focal = true;
  bool principal = false;
  bool distortion = true;
};

// What is refined of the poses, with the names and defaults of COLMAP 4's bundle adjuster:
// refine_rig_from_world (the frames' poses; without rigs, the images'), refine_sensor_from_rig
// (the cameras' poses in their rigs) and constant_rig_from_world_rotation (the frames' rotations
// held, their translations refined).
struct RefinePoses {
  bool rig_from_world = true;
  bool sensor_from_rig = true;
  bool constant_rig_from_world_rotation = false;
};

// Parses "none", "all" or a comma-separated list of focal, principal, distortion. Returns
// why the text is bad (empty when good).
std::string parse_refine_intrinsics(const std::string &text, RefineIntrinsics *out);

// What COLMAP's BundleAdjustmentConfig holds constant beyond the options, named as it names
// them: poses (flags by Model::images; in a rig, the image's frame's pose and its camera's pose
// in the rig), camera intrinsics (by Model::cameras: every parameter of the camera, in all its
// images), sensor_from_rig poses (by Model::cameras: the camera's pose in its rig, in every
// frame; a reference camera's is the identity, held anyway), points (by Model::points), and
// rig_from_world poses (by Model::frames: the frame's pose alone, its cameras' poses in the rig
// refined as the options say). An empty vector holds nothing.
struct Constants {
  std::vector<char> poses, intrinsics, sensor_from_rig, points, frames;
};

// How COLMAP 4's bundle adjuster fixes the gauge (BundleAdjustmentGauge), the 7 directions
// (a similarity) that move no reprojection: not at all; by the poses of two images
// (TWO_CAMS_FROM_WORLD: one image's whole pose and one coordinate of another's translation,
// unless the problem holds two images' poses already); by three points (THREE_POINTS, unless
// it holds three already).
enum class Gauge { None, TwoCamsFromWorld, ThreePoints };

// Which observations COLMAP's BundleAdjustmentConfig makes residuals, as COLMAP 4 chooses them:
// images (flags by Model::images; empty: every image) are the config's images, each of whose
// observations is a residual, and whose poses, cameras' poses in their rigs and intrinsics are
// refined as the options and constants say; variable_points (by Model::points) are points
// refined with every observation of theirs, in any image; and a constant point
// (Constants::points) is held with its observations in the config's images and in any other
// image that has something refined (its camera's intrinsics, or its camera's pose in a rig,
// refined for a config image). Any other point that a config image sees is refined when every
// image of its track is a config image, and held otherwise, with its observations in the config's
// images. An image outside the config has its pose held (its frame's, and its camera's in the
// rig and its intrinsics unless a config image refines them). A point whose track is shorter
// than min_track_length is left out, whatever the lists say.
struct Selection {
  std::vector<char> images, variable_points;
  int min_track_length = 0;
  // Whether the selection chooses anything: without it every point and every observation is in
  // the problem.
  bool active() const { return !images.empty() || !variable_points.empty() || min_track_length > 0; }
};

// The frames of the model that hold several images (none without rigs and frames).
std::size_t frames_of_several_images(const Model &model);

// An item or a name as a message quotes it: in single quotes, a control character as \xHH.
std::string quoted(const std::string &item);

// Lists of images, for COLMAP's constant poses (sbarefine's --hold-poses and --hold-poses-file,
// docs/formats.md). An item is matched as given, nothing trimmed: one of plain decimal digits
// without a leading zero ("0", "10"; not "010", "+10" or " 10") names the image of that IMAGE_ID
// when there is one; any other item, and such an item when no image has that IMAGE_ID, names
// every image of that NAME. An item that names no image is an error that quotes it (a control
// character in it as \xHH, so that the message stays one line).

// Images by IMAGE_ID and by NAME (names may repeat): the one matching rule of every list of
// images, the command line's and pysba's. Each hold_* sets the flags (one per image of the
// vector indexed) of the images an item names, and returns why it names none ("no image has
// the IMAGE_ID 11", "no image has the NAME 'a.png'"), empty when it names one.
class ImageIndex {
 public:
  explicit ImageIndex(const std::vector<Image> &images);
  // An item known to be an IMAGE_ID: the image of that IMAGE_ID.
  std::string hold_id(std::uint64_t id, std::vector<char> *held) const;
  // An item known to be a NAME: every image of that NAME.
  std::string hold_name(const std::string &name, std::vector<char> *held) const;
  // An item of a list's text: written as an IMAGE_ID is, the image of that IMAGE_ID when there
  // is one, else (and any other item) every image of that NAME.
  std::string hold_text(const std::string &item, std::vector<char> *held) const;

 private:
  bool flag_id(std::uint64_t id, std::vector<char> *held) const;
  bool flag_name(const std::string &name, std::vector<char> *held) const;
  std::unordered_map<std::uint32_t, std::size_t> by_id_;
  std::unordered_multimap<std::string, std::size_t> by_name_;
};

// The comma-separated items of list, in order ("all" is one item here). Returns why the list is
// bad (an empty item, numbered from 1), empty when good.
std::string split_image_list(const std::string &list, std::vector<std::string> *items);

// Holds the images named by list: "all" (every image), or items separated by commas. *held
// has one flag per Model::images (it is sized so); the flags of the images named are set, the
// others left as they are. Returns why the list is bad (an empty item, an item that names no
// image), empty when good; *held is changed only then.
std::string parse_image_list(const Model &model, const std::string &list, std::vector<char> *held);

// The same for the text of a file of names (name stands for it in messages): one NAME a line,
// matched exactly, so that a name may hold a comma, be "all" or be digits (a line is never an
// IMAGE_ID). Only the line break is taken off ("\n", or "\r\n"); a blank line is skipped (no
// image's name is empty). Errors are "NAME:LINE: why".
std::string parse_image_names(const Model &model, const std::string &text, const std::string &name,
                              std::vector<char> *held);

// Lists of identifiers, for COLMAP's other constants (sbarefine's --hold-intrinsics and
// --hold-sensor-from-rig, of CAMERA_IDs, and --hold-points, of POINT3D_IDs): "all", or items
// separated by commas, each written as an IMAGE_ID of an image list is (plain decimal digits
// without a leading zero), and matched exactly.

// Whether list is such a list of identifiers of at most max (kind names them in the message:
// "CAMERA_ID"): why not (the first bad item, quoted and numbered from 1), empty when it is.
std::string check_id_list(const std::string &list, const char *kind, std::uint64_t max);

// Flags the cameras list names: *held has one flag per Model::cameras (it is sized so), and is
// changed only when the list is good. Returns why not ("no camera has the CAMERA_ID '7'").
std::string parse_camera_list(const Model &model, const std::string &list, std::vector<char> *held);

// The same for points: one flag per Model::points ("no point has the POINT3D_ID '7'").
std::string parse_point_list(const Model &model, const std::string &list, std::vector<char> *held);

// The same for the text of a file of POINT3D_IDs (name stands for it in messages): one a line,
// as in a list; only the line break is taken off, and blank lines are skipped. Errors are
// "NAME:LINE: why".
std::string parse_point_ids(const Model &model, const std::string &text, const std::string &name,
                            std::vector<char> *held);

// A camera of one of the five models eucsbademo's camera expresses (SIMPLE_PINHOLE, PINHOLE,
// SIMPLE_RADIAL, RADIAL, OPENCV) as that camera; false for the others.
bool to_euclidean(const sbacameras::colmap_camera::Camera &c, euclidean::Camera *out);

// An eucsbademo problem as a COLMAP model, for tests and for sbagen: image j is IMAGE_ID
// 10 + 3j named img_jjjj.png with one unmatched keypoint (POINT3D_ID -1) before its
// observations, point i is POINT3D_ID 1000 + 7i with a color of its own (identifiers that are
// neither contiguous nor zero-based, as COLMAP's). FixedIntrinsics: one PINHOLE camera (id 1)
// shared by every image; otherwise camera 100 + j of image j, PINHOLE or, with distortion,
// OPENCV. False with a message for what COLMAP cannot hold (a skew, kc4, a point set without
// its dense vmask).
bool from_problem(euclidean::CameraKind kind, const std::vector<euclidean::Camera> &cameras, const eucsba::PointSet &points,
                  int width, int height, Model *out, std::string *error);

}  // namespace sbaformats::colmap

#endif  // SBA_LIB_FORMATS_COLMAP_SBA_H
