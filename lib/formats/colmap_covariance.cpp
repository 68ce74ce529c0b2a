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

namespace {

// T over the pose parameters (v t) that start at `first`: diag(d(delta)/dv, I), 6 x 6.
void tangent_map(const double *a, int first, double T[36]) {
  double J[9];
  cc::rotation_tangent_jacobian(a + first, J);
  std::fill(T, T + 36, 0.0);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) T[r * 6 + c] = J[r * 3 + c];
    T[(r + 3) * 6 + r + 3] = 1.0;
  }
}

// The upper triangle of T C T^T into P (6 x 6), T 6 x w over parameters [first, first + w)
// of the cnp x cnp block C.
void transform(const double *T, int w, const double *C, int cnp, int first, double P[36]) {
  std::fill(P, P + 36, 0.0);
  for (int r = 0; r < 6; ++r)
    for (int c = r; c < 6; ++c) {
      double s = 0;
      for (int k = 0; k < w; ++k)
        for (int l = 0; l < w; ++l) s += T[r * w + k] * C[at(first + k) * at(cnp) + at(first + l)] * T[c * w + l];
      P[r * 6 + c] = s;
    }
}

}  // namespace

CovarianceBlock pose_covariance(const double *a, const double *cov, const char *fixed, int cnp, int first) {
  double T[36], P[36];
  tangent_map(a, first, T);
  transform(T, 6, cov, cnp, first, P);
  return param_covariance(P, fixed ? fixed + first : nullptr, 6, 0, 6);
}

CovarianceBlock composed_pose_covariance(const double *a, const double *cov, const char *fixed, int cnp,
                                         const double R_s[9], const double t_f[3]) {
  double Tf[36], Ts[36];
  tangent_map(a, 0, Tf);
  tangent_map(a, 6, Ts);
  // d(cam pose)/d(frame tangent, sensor tangent): [R_s 0 I 0; 0 R_s -2[R_s t_f]x I].
  double D[72] = {0}, Rt[3];
  for (int r = 0; r < 3; ++r) Rt[r] = R_s[r * 3] * t_f[0] + R_s[r * 3 + 1] * t_f[1] + R_s[r * 3 + 2] * t_f[2];
  const double cross[9] = {0, -Rt[2], Rt[1], Rt[2], 0, -Rt[0], -Rt[1], Rt[0], 0};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      D[r * 12 + c] = D[(r + 3) * 12 + 3 + c] = R_s[r * 3 + c];
      D[(r + 3) * 12 + 6 + c] = -2.0 * cross[r * 3 + c];
    }
    D[r * 12 + 6 + r] = D[(r + 3) * 12 + 9 + r] = 1.0;
  }
  // T = D diag(Tf, Ts): 6 x 12 over the parameters v_f t_f v_s t_s.
  double T[72] = {0};
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 12; ++c) {
      const double *half = c < 6 ? Tf : Ts;
      for (int k = 0; k < 6; ++k) T[r * 12 + c] += D[r * 12 + (c < 6 ? 0 : 6) + k] * half[k * 6 + c % 6];
    }
  double P[36];
  transform(T, 12, cov, cnp, 0, P);
  // A coordinate is free when some free parameter moves it.
  char held[6];
  for (int r = 0; r < 6; ++r) {
    held[r] = 1;
    for (int c = 0; c < 12; ++c)
      if (T[r * 12 + c] != 0.0 && !(fixed && fixed[c])) held[r] = 0;
  }
  return param_covariance(P, held, 6, 0, 6);
}

CovarianceBlock param_covariance(const double *cov, const char *fixed, int cnp, int first, int count) {
  std::vector<int> columns(at(count));
  for (int k = 0; k < count; ++k) columns[at(k)] = first + k;
  return param_covariance(cov, fixed, cnp, columns.data(), count);
}

CovarianceBlock param_covariance(const double *cov, const char *fixed, int cnp, const int *columns, int count) {
  CovarianceBlock b;
  std::vector<int> taken;
  for (int k = 0; k < count; ++k)
    if (columns[k] >= 0 && !(fixed && fixed[columns[k]])) {
      b.coords.push_back(k);
      taken.push_back(columns[k]);
    }
  b.cov = sub_block(cov, cnp, taken);
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
