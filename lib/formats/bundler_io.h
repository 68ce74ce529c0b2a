/* SPDX-License-Identifier: BSD-3-Clause */
// Bundler's bundle.out (v0.3, docs/formats.md "Bundler"): a strict reader, a writer and the
// mapping onto the BAL camera model (cameras/bal_camera.h), which is Bundler's own camera:
// P = R X + t, p = -P / P_z (the camera looks down -z, y up), measured = f (1 + k1 |p|^2 +
// k2 |p|^4) p, in pixels from the image centre with y up.
//
// Errors are one line, "<file>:<line>: <message>".
#ifndef SBA_LIB_FORMATS_BUNDLER_IO_H
#define SBA_LIB_FORMATS_BUNDLER_IO_H

#include <array>
#include <string>
#include <vector>

#include "formats/bal_io.h"
#include "formats/eucsba_io.h"

namespace sbaformats {
class OutputSet;  // output_file.h
}  // namespace sbaformats

namespace sbaformats::bundler {

struct Camera {
  double f = 0, k1 = 0, k2 = 0;
  std::array<double, 9> R{};  // row-major, world to camera
  std::array<double, 3> t{};
  // Bundler writes a camera it could not place as all zeros.
  bool registered() const { return f != 0; }
};

struct View {
  int camera = 0;
  int key = 0;  // the feature's index in that image's key file
  double x = 0, y = 0;
};

struct Point {
  std::array<double, 3> xyz{};
  std::array<int, 3> rgb{};
  std::vector<View> views;
};

struct Bundle {
  std::vector<Camera> cameras;
  std::vector<Point> points;
};

// The text of a bundle file: "# Bundle file v0.3", the counts, the cameras (f k1 k2, three
// rows of R, t), the points (position, color, view list). Every number finite, colors
// 0..255, camera indices in range and each at most once per point, R a rotation (to 1e-6),
// registered cameras only in view lists, nothing after the last point.
bool parse_bundle(const std::string &text, const std::string &name, Bundle *out, std::string *error);
bool read_bundle(const std::string &path, Bundle *out, std::string *error);
// Numbers with 17 significant digits: the text reads back to the same doubles.
std::string format_bundle(const Bundle &b);
// The file appears whole or not at all; with `outputs`, when that set of a run's outputs is
// committed (output_file.h).
bool write_bundle(const std::string &path, const Bundle &b, std::string *error, OutputSet *outputs = nullptr);

// Bundler's image list (list.txt): one line per camera of the bundle, in its order, `PATH` or
// `PATH 0 FOCAL` (the focal length from the image's EXIF data). The names are what the
// bundle lacks; the text is kept to be written back as read.
struct ImageList {
  std::vector<std::string> names;  // each line's PATH
  std::string text;                // the file as read
};

// Every line (but an empty one after the last line break) is a path without blanks,
// optionally followed by 0 and a finite positive focal length; a carriage return before a
// line break is allowed.
bool parse_list(const std::string &text, const std::string &name, ImageList *out, std::string *error);
bool read_list(const std::string &path, ImageList *out, std::string *error);

// The registered cameras and every point as a BAL problem (camera k of the problem is the
// k-th registered camera; cameras[k] its index in the bundle). False with a message when a
// registered camera sees no point, naming it by names[index] when names are given.
bool to_bal(const Bundle &b, const std::string &name, bal::Problem *out, std::vector<int> *cameras,
            std::string *error, const std::vector<std::string> &names = {});
// The problem's cameras from mcon on and points from ncon on back into the bundle.
void from_bal(const bal::Problem &p, const std::vector<int> &cameras, int mcon, int ncon, Bundle *b);

// w with R(w) = R (sbacameras::bal::rotation_matrix's inverse), |w| <= pi.
void angle_axis(const std::array<double, 9> &R, double w[3]);

// An eucsbademo problem as a bundle: R and t turned to look down -z with y up, f = fu,
// k1 = kc0, k2 = kc1, measurements from each camera's principal point with y up, point i
// colored as eucsba::generated_color colors it, key i. False with a message for what Bundler
// cannot hold: ar != 1, a skew, tangential terms or kc4, a point set without its vmask.
bool from_problem(const std::vector<euclidean::Camera> &cameras, const eucsba::PointSet &points, Bundle *out,
                  std::string *error);

}  // namespace sbaformats::bundler

#endif  // SBA_LIB_FORMATS_BUNDLER_IO_H
