/* SPDX-License-Identifier: BSD-3-Clause */
// eucsbademo's text files (docs/formats.md): readers that validate strictly and report the
// first problem as one "<file>:<line>: <message>" line, and writers for the refined cameras
// and points.
//
// Common rules: values are separated by white space; blank lines and lines whose first
// non-blank character is '#' are ignored; every number must be finite; integers (nframes,
// frame indices) must be written as integers. No line (comments included) may be longer
// than 1 MiB, or in a points file than 64 bytes per value of a point seen by every camera,
// (4 + 7 * ncameras) * 64 bytes, if that is more: "<file>:<line>: line longer than N bytes".
// The rest of such a line is not read, so a file without line breaks (/dev/zero) is refused
// at once instead of being read into memory.
#ifndef SBA_LIB_FORMATS_EUCSBA_IO_H
#define SBA_LIB_FORMATS_EUCSBA_IO_H

#include <array>
#include <string>
#include <vector>

#include "cameras/euclidean.h"
#include "formats/visibility.h"

namespace sbaformats {
class OutputSet;  // output_file.h
// The camera that eucsbademo's files describe, which the other formats convert to and from.
namespace euclidean = sbacameras::euclidean;
}  // namespace sbaformats

namespace sbaformats::eucsba {

// The readers and writers return false at the first error, with "<file>:<line>: <message>" in
// *error ("<file>: <message>" where no line is concerned: open, write), as the other formats
// do. They never throw for bad input; they may throw std::bad_alloc.

// Values on a camera line of each kind: 7, 12 or 17.
int camera_file_values(euclidean::CameraKind kind);

struct CameraFile {
  euclidean::CameraKind kind = euclidean::CameraKind::FixedIntrinsics;  // from the first line's value count
  std::vector<euclidean::Camera> cameras;  // for FixedIntrinsics, k is left at its default
  int first_line = 0;           // line of the first camera, for errors about the whole file
};

// Lines of 7 (q t), 12 (fu u0 v0 ar s q t) or 17 (fu u0 v0 ar s kc0..kc4 q t) values, the same
// count on every line. Quaternions are kept as written (normalized by the model); a zero one
// is an error.
bool read_cameras(const std::string &path, CameraFile *out, std::string *error);

// Three rows of three: K = [fu s u0; 0 fv v0; 0 0 1], giving ar = fv / fu. The lower triangle
// must be (0, 0, 0) and K[2][2] = 1, fu and fv nonzero.
bool read_calibration(const std::string &path, euclidean::Intrinsics *out, std::string *error);

// How projections carry covariances in a points file.
enum class CovarianceForm {
  None,            // f x y
  UpperTriangular, // f x y cxx cxy cyy
  Full             // f x y cxx cxy cyx cyy (cxy and cyx equal)
};

// The structure and the measurements in sba's layout.
struct PointSet {
  int ncameras = 0;
  CovarianceForm form = CovarianceForm::None;
  std::vector<double> xyz;    // 3 per point
  std::vector<char> vmask;    // npoints * ncameras; vmask[i * ncameras + j] != 0 iff seen
  // The same as pairs, for point sets whose vmask would not fit (sbarefine's models): then
  // vmask is empty. The readers fill vmask.
  Visibility pairs;
  std::vector<double> x;      // 2 per projection, point by point, cameras ascending
  std::vector<double> covx;   // empty, or 4 per projection: 2x2 row-major, symmetric

  int npoints() const { return static_cast<int>(xyz.size() / 3); }
  int nprojections() const { return static_cast<int>(x.size() / 2); }
  bool has_covariances() const { return !covx.empty(); }
};

// The color the writers of a generated scene (COLMAP, Bundler, NVM) give point i: eucsbademo
// files have none, and distinct colors show a round trip that mixed points up.
inline std::array<int, 3> generated_color(int i) { return {(i * 37) & 255, (i * 11 + 64) & 255, 255 - i % 256}; }

// Calls f(i, j, x) for every projection of a point set (from its vmask, or its pairs when it
// has no vmask), point by point with the cameras ascending: point i seen by camera j at x[0],
// x[1].
template <class F>
void for_each_projection(const PointSet &points, F f) {
  if (points.vmask.empty()) {
    for (std::size_t k = 0; k < points.pairs.size(); ++k)
      f(points.pairs.point[k], points.pairs.camera[k], &points.x[2 * k]);
    return;
  }
  const std::size_t m = static_cast<std::size_t>(points.ncameras);
  std::size_t k = 0;
  for (int i = 0; i < points.npoints(); ++i)
    for (std::size_t j = 0; j < m; ++j)
      if (points.vmask[static_cast<std::size_t>(i) * m + j]) {
        f(i, static_cast<int>(j), &points.x[2 * k]);
        ++k;
      }
}

// Lines `X Y Z nframes` followed by nframes projections `f x y` (each optionally followed by
// its covariance, one form for the whole file). Frames may come in any order within a line
// (they are sorted) but each at most once, and must lie in [0, ncameras). Covariances must
// be positive definite.
bool read_points(const std::string &path, int ncameras, PointSet *out, std::string *error);

// A whole eucsbademo problem: the camera kind comes from the camera file; a calibration file
// goes with 7-value camera lines and only with them.
struct Problem {
  euclidean::CameraKind kind = euclidean::CameraKind::FixedIntrinsics;
  std::vector<euclidean::Camera> cameras;  // for FixedIntrinsics, k is the calibration
  PointSet points;
};
// calib_path empty: no calibration file.
bool load_problem(const std::string &cams_path, const std::string &pts_path, const std::string &calib_path,
                  Problem *out, std::string *error);

// ---- writers (%.10e numbers) ----
// Each file appears whole or not at all; with `outputs`, when that set of a run's outputs is
// committed (output_file.h).

// Cameras in the input format of their kind, quaternions as given (callers pass them unit
// with w >= 0, as CameraModel::camera returns them).
bool write_cameras(const std::string &path, euclidean::CameraKind kind,
                   const std::vector<euclidean::Camera> &cameras, std::string *error, OutputSet *outputs = nullptr);
// One `X Y Z` line per point.
bool write_points_xyz(const std::string &path, const std::vector<double> &xyz, std::string *error,
                      OutputSet *outputs = nullptr);
// A points file (readable by read_points) with the coordinates xyz and the projections and
// covariances of tracks (by vmask or by pairs), in tracks' covariance form.
bool write_points(const std::string &path, const PointSet &tracks, const std::vector<double> &xyz,
                  std::string *error, OutputSet *outputs = nullptr);
// Reads `X Y Z` lines back.
bool read_points_xyz(const std::string &path, std::vector<double> *xyz, std::string *error);

}  // namespace sbaformats::eucsba

#endif  // SBA_LIB_FORMATS_EUCSBA_IO_H
