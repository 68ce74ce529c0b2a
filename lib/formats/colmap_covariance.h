/* SPDX-License-Identifier: BSD-3-Clause */
// The covariance of a refined COLMAP model in COLMAP's convention (docs/formats.md,
// "Covariances"), which sbarefine --covariance writes and pysba.refine_colmap(covariance=True)
// returns: colmap::Problem::covariance computes it from the library's blocks through the
// functions here, write_covariances writes it.
//
// The blocks are those of (J^T J)^-1, the covariance for reprojection errors of unit variance
// in pixels, as pycolmap's estimate_ba_covariance gives them; sigma2, the residual variance,
// scales them to the errors the model has. Poses are over COLMAP's tangent, [rotation,
// translation]: the rotation's increment delta of q = [cos|delta|, sin|delta| delta/|delta|] q_hat
// (cameras/colmap_camera.h, rotation_tangent_jacobian), the translation's t = t_hat + dt.
// Held coordinates are left out of a block, as pycolmap leaves them out; a block all of whose
// coordinates are held is not given.
#ifndef SBA_LIB_FORMATS_COLMAP_COVARIANCE_H
#define SBA_LIB_FORMATS_COLMAP_COVARIANCE_H

#include <cstdint>
#include <string>
#include <vector>

#include "formats/output_file.h"

namespace sbaformats::colmap {

// One block: of a pose (coordinates 0..5: rx ry rz tx ty tz), of a COLMAP camera's
// parameters (coordinate k: its parameter k in COLMAP's order) or of a point (x y z).
struct CovarianceBlock {
  std::uint64_t id = 0;     // IMAGE_ID, FRAME_ID, CAMERA_ID or POINT3D_ID
  std::string name;         // an image's NAME; empty for the others
  std::vector<int> coords;  // the free coordinates, ascending
  std::vector<double> cov;  // coords.size() squared, row-major
};

// What Problem::covariance computes beyond the poses and cameras.
struct CovarianceOptions {
  bool points = false;       // every free point's block too
  // sba_covariance_request::point_damping. COLMAP's default (BACovarianceOptions.damping), so
  // that the blocks are the numbers a COLMAP user gets from it; 0: (J^T J)^-1 itself.
  double point_damping = 1e-8;
};

struct Covariances {
  double sigma2 = 0;  // the residual variance: ||e||^2 / (measurements - rank)
  int rank = 0;       // rank of J^T J over the free parameters
  int nfree = 0;      // the free parameters (the camera unknowns and the free points')
  // Each image's cam_from_world. With rigs (frames of several images), also each frame's
  // rig_from_world and each camera's sensor_from_rig (not a rig's reference camera's).
  std::vector<CovarianceBlock> images, frames, sensors;
  std::vector<CovarianceBlock> cameras;  // each COLMAP camera's refined parameters
  std::vector<CovarianceBlock> points;   // each free point, marginal (cameras not held fixed)
};

// The covariance of the pose at parameters [first, first + 6) of an sba camera of the
// models of cameras/colmap_camera.h (v t: its local rotation and translation) in COLMAP's
// tangent: T cov T^T with T = diag(d(delta)/dv, I) at the camera's parameters a, cov its
// cnp x cnp block of sba's covariance, fixed its held flags (cnp of them, or null).
CovarianceBlock pose_covariance(const double *a, const double *cov, const char *fixed, int cnp, int first);
// The covariance of the pose cam_from_world = sensor_from_rig rig_from_world of an image of
// a rig (cameras/colmap_camera.h's RigCameraModel: a = v_f t_f v_s t_s ...) in COLMAP's
// tangent, from the 12 x 12 of both poses and their cross-covariance: to first order
// delta_c = delta_s + R_s delta_f and dt_c = R_s dt_f - 2 [R_s t_f]x delta_s + dt_s, with R_s
// the sensor's rotation (row-major) and t_f the frame's translation at the estimate. A
// coordinate that no free parameter moves is left out.
CovarianceBlock composed_pose_covariance(const double *a, const double *cov, const char *fixed, int cnp,
                                         const double R_s[9], const double t_f[3]);
// The covariance of `count` parameters from `first` of a cnp x cnp block (a camera's, or a
// point's with cnp = first + count), over those that fixed (cnp flags, or null) leaves free.
CovarianceBlock param_covariance(const double *cov, const char *fixed, int cnp, int first, int count);
// The same for `count` parameters at the columns `columns` of the block, -1 for a parameter the
// block does not carry (left out, as a held one is).
CovarianceBlock param_covariance(const double *cov, const char *fixed, int cnp, const int *columns, int count);

// The covariances as text, a record per line (docs/formats.md):
//   SIGMA2 s RANK r NFREE f
//   IMAGE IMAGE_ID NAME COORDS values...   FRAME FRAME_ID COORDS values...
//   SENSOR CAMERA_ID COORDS values...      CAMERA CAMERA_ID COORDS values...
//   POINT POINT3D_ID COORDS values...
// COORDS names the block's coordinates, comma-separated (rx,ry,rz,tx,ty,tz; a camera's
// parameter indices; x,y,z), and the values are the block row by row, %.17g.
std::string covariance_text(const Covariances &c);

// covariance_text into the file path (into *outputs, published with the run's other files).
bool write_covariances(const std::string &path, const Covariances &c, std::string *error, OutputSet *outputs);

}  // namespace sbaformats::colmap

#endif  // SBA_LIB_FORMATS_COLMAP_COVARIANCE_H
