/* SPDX-License-Identifier: BSD-3-Clause */
// VisualSFM's NVM files (NVM_V3, docs/formats.md "VisualSFM NVM files"): a strict reader of
// the first model, a writer that puts back everything after it as it came, and the mapping
// onto eucsbademo's camera model (cameras/euclidean.h).
//
// An NVM camera: X_c = R(q) (X - C) with q = (qw qx qy qz) world to camera and C the camera
// centre; the projection is f X_c / Z_c in pixels from the image centre (x right, y down).
// VisualSFM's radial distortion acts on the measurement: the undistorted measurement is
// m (1 + k |m|^2). That is not a projection model sba's callbacks serve with k free (the
// measurement would depend on a parameter), so k is held: the measurements are undistorted
// once with each camera's k, and the camera is eucsbademo's with u0 = v0 = 0, ar = 1, no skew
// and no distortion terms; only the focal length may be refined besides pose and structure.
//
// Errors are one line, "<file>:<line>: <message>", or "<file>: <message>" for the model.
#ifndef SBA_LIB_FORMATS_NVM_IO_H
#define SBA_LIB_FORMATS_NVM_IO_H

#include <array>
#include <string>
#include <vector>

#include "cameras/euclidean.h"
#include "formats/eucsba_io.h"

namespace sbaformats {
class OutputSet;  // output_file.h
}  // namespace sbaformats

namespace sbaformats::nvm {

struct Camera {
  std::string name;  // the image file, one token
  double f = 0;
  std::array<double, 4> q{1, 0, 0, 0};  // qw qx qy qz: world to camera
  std::array<double, 3> c{};            // the camera centre
  double k = 0;                         // radial distortion of the measurements
};

struct Measurement {
  int camera = 0;
  int feature = 0;  // the feature's index in that image's feature file
  double x = 0, y = 0;
};

struct Point {
  std::array<double, 3> xyz{};
  std::array<int, 3> rgb{};
  std::vector<Measurement> measurements;
};

// The first model of a file, the header line (with any calibration tokens after NVM_V3) and
// the rest of the file after the model, neither of them interpreted.
struct Model {
  std::string header = "NVM_V3";
  std::vector<Camera> cameras;
  std::vector<Point> points;
  // What follows the model's last value and the line break after it: further models, the
  // count of 0 that ends them, the PLY section, anything.
  std::string rest;
};

// The header line starting with the token NVM_V3, the number of cameras (at least one),
// per camera `name f qw qx qy qz cx cy cz k 0`, the number of points, per point
// `x y z r g b n` and n measurements `camera feature x y`. Every number finite, f > 0, q
// nonzero, colors 0..255, camera indices in range and each at most once per point, at least
// one measurement per point, counts the text can hold.
bool parse_nvm(const std::string &text, const std::string &name, Model *out, std::string *error);
bool read_nvm(const std::string &path, Model *out, std::string *error);
// Numbers with 17 significant digits, so that the text reads back to the same doubles; the
// rest of the file after the model as it was read.
std::string format_nvm(const Model &m);
// The file appears whole or not at all; with `outputs`, when that set of a run's outputs is
// committed (output_file.h).
bool write_nvm(const std::string &path, const Model &m, std::string *error, OutputSet *outputs = nullptr);

// Whether the measurements look measured from the image's corner rather than from its centre
// (as NVM files written by COLMAP hold them), which no focal length or pose can fit. Judged on
// all measurements of the model together, and only on 100 or more: at least 99% of them have
// x >= 0 and y >= 0, and on each axis their mean exceeds their standard deviation. Centred
// measurements of a real reconstruction spread over all four quadrants (about a quarter in
// any one); corner-based ones fill one, their mean about 1.7 standard deviations from 0.
bool looks_uncentred(const Model &m);

// An NVM file's problem through eucsbademo's camera model (to_sba fills it).
struct SbaProblem {
  std::vector<euclidean::Camera> cameras;  // one per camera, in file order
  eucsba::PointSet points;                 // one per 3D point, in file order; visibility as pairs
  int nccalib = 5, ncdist = 5;             // trailing intrinsics / distortion terms held
};

// The model as a problem of eucsbademo's VaryingIntrinsicsDistortion cameras, one per NVM
// camera in file order, every intrinsic held but the focal length when refine_focal
// (nccalib 4, else 5; ncdist 5). False with a message for a model without points, a camera
// that sees none, and a translation -R C or an undistorted measurement that overflows.
bool to_sba(const Model &m, bool refine_focal, const std::string &name, SbaProblem *out,
            std::string *error);
// The estimate p (as eucsbademo lays it out) back into the model: f, q and C of the cameras
// from mcon on, the points from ncon on. Everything else stays as it was read.
void from_sba(const euclidean::CameraModel &sba_model, const double *p, int mcon, int ncon, Model *m);

// An eucsbademo problem as a model, for tests and for sbagen: camera j is img_jjjj.jpg with
// k = 0, measurements from each camera's principal point, point i colored as
// eucsba::generated_color colors it and feature index i in every image. False with a message for
// what NVM cannot hold: ar != 1, a skew, distortion terms, a point set without its vmask.
bool from_problem(const std::vector<euclidean::Camera> &cameras, const eucsba::PointSet &points, Model *out,
                  std::string *error);

}  // namespace sbaformats::nvm

#endif  // SBA_LIB_FORMATS_NVM_IO_H
