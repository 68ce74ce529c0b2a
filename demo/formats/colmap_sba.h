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
// NVM files (nvm_io.h) still map onto eucsbademo's camera (SbaProblem below).
#ifndef SBA_DEMO_COLMAP_SBA_H
#define SBA_DEMO_COLMAP_SBA_H

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

// Parses "none", "all" or a comma-separated list of focal, principal, distortion. Returns
// why the text is bad (empty when good).
std::string parse_refine_intrinsics(const std::string &text, RefineIntrinsics *out);

// An NVM file's problem through eucsbademo's camera model (nvm::to_sba fills it).
struct SbaProblem {
  std::vector<euclidean::Camera> cameras;  // one per camera, in file order
  std::vector<int> images;                 // unused by nvm::to_sba: empty
  eucsba::PointSet points;                 // one per 3D point, in file order; visibility as pairs
  int nccalib = 5, ncdist = 5;             // trailing intrinsics / distortion terms held
};

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
  int held_poses = 0;            // images whose pose is held
};

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

// The problem of a model checked by check_model. held_pose: one flag per Model::images (or
// empty for none). mcon: the sba cameras below it are held by the solve (sba's mcon); a COLMAP
// camera that one of them uses has its parameters held in all its images, so that what is
// written back is one calibration. An image that sees no point has no sba camera (nothing
// places it): it is held out of the problem, and from_sba leaves it as it was. A model whose
// frames hold several images (a rig of several cameras, whose images keep one rig pose) is
// refused: its images' poses are not free unknowns.
bool to_sba(const Model &model, const RefineIntrinsics &refine, const std::vector<char> &held_pose, int mcon,
            const std::string &name, ColmapProblem *out, std::string *error);

// Writes the estimate p (m cnp-vectors, then n points) back into the model: the poses of the
// sba cameras from mcon on that are not held, the points from ncon on, the parameters of each
// COLMAP camera that are not held (once per camera: a group's from its first sba camera),
// and each refined point's ERROR as its mean reprojection error in pixels; with rigs and
// frames, the frame of each image whose pose is written gets that pose (frames_from_poses).
// Everything else stays as it was read, bit for bit.
void from_sba(const sbacameras::colmap_camera::CameraModel &sba_model, const ColmapProblem &problem, const double *p,
              int mcon, int ncon, Model *model);

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

#endif  // SBA_DEMO_COLMAP_SBA_H
