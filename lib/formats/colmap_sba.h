/* SPDX-License-Identifier: BSD-3-Clause */
// A COLMAP model as an sba problem of COLMAP's own camera models (cameras/colmap_camera.h,
// docs/formats.md, "COLMAP sparse models"), and the refined estimate written back into it.
//
// Every image that sees a point is one sba camera, a_j = (v t params padding): its pose in
// the rotation parametrization of euclidean.h and a copy of its COLMAP camera's parameters
// in COLMAP's order; every 3D point one sba point. A COLMAP camera that several of those
// images use is one group (sba_ext_options::cam_group, numbered by its first sba camera)
// whose parameter slots are shared (cam_shared): it is refined once, as COLMAP does. A camera
// used by one image is in no group (-1): its copy is its own. Which parameters are held goes
// per camera into cam_fixed: the padding and EQUIRECTANGULAR's size (w h) always, and by
// COLMAP's bundle adjustment options the focal length (f or fx fy), the principal point
// (cx cy), the extra parameters (the rest), and the poses of the images the caller names.
//
// A model whose frames hold several images (rigs of several cameras exposed together, COLMAP
// 4), or one with rigs and frames whose frames' poses are held in part or whole (COLMAP 4's
// options), is refined as COLMAP 4 refines it: every image that sees a point is an sba camera of the
// rig camera model, a_j = (frame pose | sensor pose | params padding) (colmap_camera.h), and
// sba_ext_options::cam_param_group shares each frame's pose among its images, each camera's
// pose in its rig among the frames, and each COLMAP camera's parameters among its images; a
// rig's reference camera has the identity for its pose there, held. A frame's images then
// keep one rig pose, and a camera one pose in its rig, bit for bit.
#ifndef SBA_LIB_FORMATS_COLMAP_SBA_H
#define SBA_LIB_FORMATS_COLMAP_SBA_H

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
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

// A COLMAP model's problem.
struct ColmapProblem {
  std::vector<sbacameras::colmap_camera::Camera> cameras;  // one per image that sees a point, in file order
  std::vector<int> images;   // each camera's index in Model::images
  eucsba::PointSet points;   // one per 3D point, in file order; visibility as pairs
  int cnp = 0;               // colmap_camera::camera_params(the largest parameter count of the cameras used)
  std::vector<char> cam_fixed;   // m*cnp, camera j's at j*cnp: nonzero for a held parameter
  std::vector<int> cam_group;    // m: the group of a shared COLMAP camera, -1 for none
  std::vector<char> cam_shared;  // cnp: the parameter slots (not the pose) a group shares
  int shared_cameras = 0;        // COLMAP cameras refined once for several images
  int held_poses = 0;            // images whose pose is held, whether they see points or not
  // Images that see no point (Model::images without a camera of the problem) whose frame's pose
  // or camera's pose in the rig is refined (rigged only): they keep their place there, and move.
  int unseen_moved = 0;
  // A model whose frames hold several images: cameras, cam_group and cam_shared are empty and
  // these hold the problem instead.
  bool rigged = false;
  std::vector<sbacameras::colmap_camera::RigImage> rig_images;  // one per sba camera, as cameras
  std::vector<ImagePlace> places;   // each sba camera's frame, rig and sensor
  std::vector<int> cam_param_group;  // m*cnp: frame poses by frame, sensor poses by camera, intrinsics by camera
  int frames = 0, held_frames = 0;    // the frames of the sba cameras, and those whose pose is held
  int sensors = 0, held_sensors = 0;  // their cameras that are not a rig's reference, and those held
  int held_intrinsics = 0;  // COLMAP cameras of the sba cameras whose intrinsics are constant (Constants)
  // Problem point k is Model::points[point_order[k]] (empty: the file's order, k itself), and the
  // first held_points of them are held (sba's ncon, in the solve and in from_sba).
  std::vector<int> point_order;
  int held_points = 0;
};

// What COLMAP's BundleAdjustmentConfig holds constant beyond the options, named as it names
// them: poses (flags by Model::images; in a rig, the image's frame's pose and its camera's pose
// in the rig), camera intrinsics (by Model::cameras: every parameter of the camera, in all its
// images), sensor_from_rig poses (by Model::cameras: the camera's pose in its rig, in every
// frame; a reference camera's is the identity, held anyway), points (by Model::points). An
// empty vector holds nothing.
struct Constants {
  std::vector<char> poses, intrinsics, sensor_from_rig, points;
};

// The frames of the model that hold several images (none without rigs and frames).
std::size_t frames_of_several_images(const Model &model);

// Lists of images, for COLMAP's constant poses (sbarefine's --hold-poses and --hold-poses-file,
// docs/formats.md). An item is matched as given, nothing trimmed: one of plain decimal digits
// without a leading zero ("0", "10"; not "010", "+10" or " 10") names the image of that IMAGE_ID
// when there is one; any other item, and such an item when no image has that IMAGE_ID, names
// every image of that NAME. An item that names no image is an error that quotes it (a control
// character in it as \xHH, so that the message stays one line).

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

// The problem of a model checked by check_model. held_pose: one flag per Model::images (or
// empty for none). mcon: the sba cameras below it are held by the solve (sba's mcon); a COLMAP
// camera that one of them uses has its parameters held in all its images, so that what is
// written back is one calibration. An image that sees no point has no sba camera (nothing
// places it): it is held out of the problem, and from_sba leaves it as it was (in a rig, it
// keeps its place in its frame).
// Without rigs and frames, or with frames of one image each and poses.rig_from_world without
// poses.constant_rig_from_world_rotation, each image's pose is its own 6 parameters, held for a
// held_pose image, without poses.rig_from_world for every image (there are no rigs), its
// rotation's 3 held with poses.constant_rig_from_world_rotation; poses.sensor_from_rig changes
// nothing (a frame of one image, free, takes up any change of its camera's pose in the rig).
// Otherwise (rigged), a frame's pose is held in all its images without poses.rig_from_world,
// or when one of its images is a held_pose image (one that sees no point included) or below
// mcon; its rotation with poses.constant_rig_from_world_rotation; a camera's pose in its rig in
// all its images without poses.sensor_from_rig, or when one of its images is a held_pose image
// (seeing points or not) or below mcon: holding an image's pose holds both parts of it, so that
// it comes back as it was read.
// With constants beyond the poses (constants.poses is held_pose): constant intrinsics are held
// as mcon holds a camera's (in all its images, out of any group); constant sensor_from_rig poses
// as poses.sensor_from_rig holds them all (in a rigged problem; otherwise nothing changes, as
// there); constant points, and the first ncon points, are put first in the problem's points, and
// out->held_points counts them (see ColmapProblem; without constant points it is ncon, and the
// order the file's).
bool to_sba(const Model &model, const RefineIntrinsics &refine, const RefinePoses &poses,
            const Constants &constants, int mcon, int ncon, const std::string &name, ColmapProblem *out,
            std::string *error);
bool to_sba(const Model &model, const RefineIntrinsics &refine, const RefinePoses &poses,
            const std::vector<char> &held_pose, int mcon, const std::string &name, ColmapProblem *out,
            std::string *error);

// Why the solve of a problem to_sba made of model cannot start, empty when it can: the first
// observation, in the problem's order, whose squared reprojection error at the start is not
// finite (a parameter that overflows the projection, as OPENCV's k1 = 1e200 does), named by its
// image, that image's camera and the point: "NAME: image 13 (a.png), camera 101 (OPENCV):
// point 1007 projects to (1.2e+202, 3.4e+201) px, where its squared reprojection error is not
// finite". project(j, i, x) gives sba camera j's projection of point i at the start.
std::string nonfinite_error(const Model &model, const ColmapProblem &problem, const std::string &name,
                            const std::function<void(int j, int i, double x[2])> &project);

// Writes the estimate p (m cnp-vectors, then n points) back into the model: the poses of the
// sba cameras from mcon on that are not held, the problem's points from ncon on (each into its
// place in the model, point_order), the parameters of each
// COLMAP camera that are not held (once per camera: a group's from its first sba camera),
// and each refined point's ERROR as its mean reprojection error in pixels; with rigs and
// frames, the frame of each image whose pose is written gets that pose (frames_from_poses).
// Everything else stays as it was read, bit for bit.
void from_sba(const sbacameras::colmap_camera::CameraModel &sba_model, const ColmapProblem &problem, const double *p,
              int mcon, int ncon, Model *model);

// The same for a rigged problem: the pose of each frame and of each camera in its rig that is
// not held (once: from their first sba camera from mcon on), the parameters of each COLMAP
// camera that are not held, the points from ncon on and their ERROR; then every image's pose
// is composed from its frame's (poses_from_frames), as COLMAP 4 reads it. A held rotation or
// translation keeps its bits.
void from_sba(const sbacameras::colmap_camera::RigCameraModel &sba_model, const ColmapProblem &problem,
              const double *p, int mcon, int ncon, Model *model);

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
