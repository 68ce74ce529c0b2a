/* SPDX-License-Identifier: BSD-3-Clause */
// BAL ("Bundle Adjustment in the Large", Agarwal et al., ECCV 2010) problem files: a strict
// reader for plain and bzip2-compressed text, the conversion to sba's point-by-point layout,
// and a writer. The camera model itself is in cameras/bal_camera.h. Neither depends on the sba
// library.
//
// The format is a stream of numbers separated by any white space (lines do not matter):
//   ncameras npoints nobservations
//   nobservations times:  camera point x y      (zero-based indices, pixels)
//   ncameras times:       9 camera parameters   (w1 w2 w3  t1 t2 t3  f k1 k2)
//   npoints times:        3 point coordinates   (X Y Z)
// and nothing after the last point.
#ifndef SBA_LIB_FORMATS_BAL_IO_H
#define SBA_LIB_FORMATS_BAL_IO_H

#include <cstddef>
#include <string>
#include <vector>

#include "cameras/bal_camera.h"
#include "formats/visibility.h"

namespace sbaformats {
class OutputSet;  // output_file.h
}  // namespace sbaformats

namespace sbaformats::bal {

// The sizes are the camera model's (cameras/bal_camera.h).
using sbacameras::bal::kCameraParams;
using sbacameras::bal::kPointParams;

struct Observation {
  int camera = 0;
  int point = 0;
  double x = 0, y = 0;
};

// A problem as the file holds it.
struct Problem {
  int ncameras = 0;
  int npoints = 0;
  std::vector<Observation> observations;  // in file order
  std::vector<double> cameras;            // kCameraParams per camera
  std::vector<double> points;             // kPointParams per point

  int nobservations() const { return static_cast<int>(observations.size()); }
  double *camera(int j) { return cameras.data() + static_cast<std::size_t>(j) * kCameraParams; }
  const double *camera(int j) const { return cameras.data() + static_cast<std::size_t>(j) * kCameraParams; }
  double *point(int i) { return points.data() + static_cast<std::size_t>(i) * kPointParams; }
  const double *point(int i) const { return points.data() + static_cast<std::size_t>(i) * kPointParams; }
};

// Reads a BAL file. A file that starts with the bzip2 signature "BZh" is decompressed
// (several concatenated bzip2 streams are accepted, as pbzip2 writes them), whatever its
// name. Validation is strict: the three counts positive and within int range, at most one
// observation per (camera, point) pair, indices within range, integers written as integers,
// every number finite, exactly the values the header announces and nothing after them.
// On failure returns false with one line "<path>: <message>" in *error (when not null); the
// message names the line and the observation, camera or point concerned. May throw
// std::bad_alloc.
//
// The text is parsed as it is read (or decompressed), never held whole, and memory grows
// only with the values stored. Reading stops at the first value beyond those the header
// announces ("more data than the header announces (...)"), at a run of more than 4096 bytes
// without white space (no number is that long: a binary file, /dev/zero) and at more than
// 1 MiB of white space in a row. After a parse error in bzip2 data, up to one block's worth
// more (48 MiB) is decompressed and discarded, so that a damaged block is reported as
// "corrupt bzip2 data" rather than as the garbage it produced.
bool read_problem(const std::string &path, Problem *out, std::string *error);

// The same from text already in memory; name is used in the messages in place of the path.
bool parse_problem(const std::string &text, const std::string &name, Problem *out,
                   std::string *error);

// What sba's C API takes, for motion and structure refinement.
struct SbaLayout {
  int n = 0;                // points
  int m = 0;                // cameras
  Visibility vis;  // which camera sees which point, measurement by measurement
  std::vector<double> x;    // 2 per observation, sorted by (point, camera)
  std::vector<int> order;   // order[k]: index in Problem::observations of sba measurement k
  std::vector<double> p;    // m*9 camera parameters followed by n*3 point coordinates

  int nobservations() const { return static_cast<int>(order.size()); }
};

// Sorts the observations point by point with cameras ascending, as sba lays out x, and
// builds the visibility and the initial parameter vector. Two observations of the same point by the
// same camera have no place in sba's layout: false with "<name>: ..." in *error. (The reader
// already refuses them; this guards problems built in memory.) May throw std::bad_alloc.
bool to_sba(const Problem &problem, const std::string &name, SbaLayout *out, std::string *error);

// Copies sba's parameter vector p (laid out as SbaLayout::p) back into the problem.
void from_sba_params(const double *p, Problem *problem);

// Writes the problem in BAL format, observations in their order and every parameter on its
// own line with 17 significant digits (the values read back exactly). A path ending in
// ".bz2" is bzip2-compressed. False with "<path>: <message>" in *error on failure. The file
// appears whole or not at all; with `outputs`, when that set of a run's outputs is committed
// (output_file.h).
bool write_problem(const std::string &path, const Problem &problem, std::string *error,
                   OutputSet *outputs = nullptr);

}  // namespace sbaformats::bal

#endif  // SBA_LIB_FORMATS_BAL_IO_H
