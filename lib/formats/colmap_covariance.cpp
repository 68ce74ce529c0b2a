// SPDX-License-Identifier: BSD-3-Clause
#include "formats/colmap_covariance.h"

#include <algorithm>
#include <cstddef>
#include <cstdio>

#include "cameras/colmap_camera.h"

namespace sbaformats::colmap {

namespace cc = sbacameras::colmap_camera;

namespace {

constexpr const char *kPoseCoords[] = {"rx", "ry", "rz", "tx", "ty", "tz"};
constexpr const char *kPointCoords[] = {"x", "y", "z"};

std::size_t at(int k) { return static_cast<std::size_t>(k); }

// The entries of the n x n row-major C over `coords`, its upper triangle mirrored: the
// library's blocks are symmetric only up to the rounding of the order of their sums.
std::vector<double> sub_block(const double *C, int n, const std::vector<int> &coords) {
  std::vector<double> out;
  for (int r : coords)
    for (int c : coords) out.push_back(C[at(std::min(r, c)) * at(n) + at(std::max(r, c))]);
  return out;
}

}  // namespace

CovarianceBlock pose_covariance(const double *a, const double *cov, const char *fixed, int cnp, int first) {
  double T[36] = {0};
  double J[9];
  cc::rotation_tangent_jacobian(a + first, J);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) T[r * 6 + c] = J[r * 3 + c];
    T[(r + 3) * 6 + r + 3] = 1.0;
  }
  double P[36] = {0};
  for (int r = 0; r < 6; ++r)
    for (int c = r; c < 6; ++c) {
      double s = 0;
      for (int k = 0; k < 6; ++k)
        for (int l = 0; l < 6; ++l) s += T[r * 6 + k] * cov[at(first + k) * at(cnp) + at(first + l)] * T[c * 6 + l];
      P[r * 6 + c] = s;
    }
  return param_covariance(P, fixed ? fixed + first : nullptr, 6, 0, 6);
}

CovarianceBlock param_covariance(const double *cov, const char *fixed, int cnp, int first, int count) {
  CovarianceBlock b;
  for (int k = 0; k < count; ++k)
    if (!fixed || !fixed[first + k]) b.coords.push_back(k);
  b.cov = sub_block(cov + at(first) * at(cnp + 1), cnp, b.coords);
  return b;
}

namespace {

void append_block(const char *kind, const CovarianceBlock &b, const char *const *names, std::string *text) {
  if (b.coords.empty()) return;
  char num[40];
  *text += kind;
  *text += ' ' + std::to_string(b.id) + (b.name.empty() ? "" : " " + b.name) + ' ';
  for (std::size_t k = 0; k < b.coords.size(); ++k)
    *text += (k ? "," : "") + (names ? std::string(names[b.coords[k]]) : std::to_string(b.coords[k]));
  for (double v : b.cov) {
    std::snprintf(num, sizeof num, " %.17g", v);
    *text += num;
  }
  *text += '\n';
}

}  // namespace

std::string covariance_text(const Covariances &c) {
  char head[160];
  std::snprintf(head, sizeof head, "SIGMA2 %.17g RANK %d NFREE %d\n", c.sigma2, c.rank, c.nfree);
  std::string text =
      "# Covariances of a refined COLMAP model for reprojection errors of unit variance (pixels^2;\n"
      "# times SIGMA2 for the errors the model has): poses over COLMAP's tangent [rotation,\n"
      "# translation], a record per line, held coordinates left out (docs/formats.md)\n";
  text += head;
  for (const CovarianceBlock &b : c.images) append_block("IMAGE", b, kPoseCoords, &text);
  for (const CovarianceBlock &b : c.frames) append_block("FRAME", b, kPoseCoords, &text);
  for (const CovarianceBlock &b : c.sensors) append_block("SENSOR", b, kPoseCoords, &text);
  for (const CovarianceBlock &b : c.cameras) append_block("CAMERA", b, nullptr, &text);
  for (const CovarianceBlock &b : c.points) append_block("POINT", b, kPointCoords, &text);
  return text;
}

bool write_covariances(const std::string &path, const Covariances &c, std::string *error, OutputSet *outputs) {
  return write_whole_file(path, covariance_text(c), error, outputs);
}

}  // namespace sbaformats::colmap
