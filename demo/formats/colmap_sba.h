/* SPDX-License-Identifier: BSD-3-Clause */
// A COLMAP model as a problem of eucsbademo's camera model (docs/formats.md, "COLMAP sparse
// models"), and the refined estimate written back into the model.
//
// Every image is one sba camera with its own copy of its COLMAP camera's intrinsics, every
// 3D point one sba point. COLMAP's pose is already eucsbademo's: qw qx qy qz and t map world
// to camera coordinates, and both use pixel coordinates as measured, so the principal point
// and the POINTS2D go over unchanged. The intrinsics map onto K = [fu s u0; 0 fu*ar v0] and
// Bouguet's distortion kc = (k1 k2 p1 p2 k3), which is OpenCV's:
//   SIMPLE_PINHOLE f cx cy         fu = f, u0 = cx, v0 = cy, ar = 1
//   PINHOLE fx fy cx cy            fu = fx, ar = fy / fx
//   SIMPLE_RADIAL f cx cy k        kc0 = k
//   RADIAL f cx cy k1 k2           kc0 = k1, kc1 = k2
//   OPENCV fx fy cx cy k1 k2 p1 p2 kc0..kc3 = k1 k2 p1 p2
// The terms a model lacks are zero and always held.
#ifndef SBA_DEMO_COLMAP_SBA_H
#define SBA_DEMO_COLMAP_SBA_H

#include <string>
#include <vector>

#include "cameras/euclidean.h"
#include "formats/colmap_io.h"
#include "formats/eucsba_io.h"

namespace sbaformats::colmap {

// Which intrinsics are refined. COLMAP's bundle adjuster refines the focal length and the
// distortion and holds the principal point; so does the default here. The aspect ratio
// fy / fx of PINHOLE and OPENCV is held (fx and fy move together).
struct RefineIntrinsics {
  bool focal = true;
  bool principal = false;
  bool distortion = true;
};

// Parses "none", "all" or a comma-separated list of focal, principal, distortion. Returns
// why the text is bad (empty when good). The principal point is refined only with the focal
// length (sba holds a trailing run of (fu u0 v0 ar s)).
std::string parse_refine_intrinsics(const std::string &text, RefineIntrinsics *out);

struct SbaProblem {
  std::vector<euclidean::Camera> cameras;  // one per image that sees a point, in file order
  std::vector<int> images;                 // to_sba: each camera's index in Model::images (nvm::to_sba: empty)
  eucsba::PointSet points;              // one per 3D point, in file order; visibility as pairs
  int nccalib = 5, ncdist = 5;          // trailing intrinsics / distortion terms held
};

// The problem of a model checked by check_model. Refining the intrinsics of a camera that
// several images share has no counterpart in sba (each image's intrinsics are its own
// parameters): refused, with a message naming the camera. An image that sees no point has no
// sba camera (nothing places it): it is held out of the problem, and from_sba leaves it as it
// was. The distortion terms refined are those every camera model has.
bool to_sba(const Model &model, const RefineIntrinsics &refine, const std::string &name, SbaProblem *out,
            std::string *error);

// Writes the estimate p (m cnp-vectors, then n points, as eucsbademo lays them out) back
// into the model: poses of the sba cameras' images from mcon on, points from ncon on, the refined
// intrinsics of their cameras, and each refined point's ERROR as its mean reprojection error
// in pixels. Everything else stays as it was read.
void from_sba(const euclidean::CameraModel &sba_model, const SbaProblem &problem, const double *p, int mcon, int ncon,
              Model *model);

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
