/* SPDX-License-Identifier: BSD-3-Clause */
// A synthetic bundle adjustment problem for the driver tests: cameras on an arc looking at
// a cloud of points, pinhole projection with Euler-angle rotations (an easy analytic
// Jacobian), known ground truth, optional pixel noise.
#ifndef SBA_TESTS_SYNTH_H
#define SBA_TESTS_SYNTH_H

#include <cmath>
#include <random>
#include <vector>

#include "sba.h"

namespace synth {

constexpr int kCnp = 6, kPnp = 3, kMnp = 2;
constexpr double kFocal = 500.0, kCx = 320.0, kCy = 240.0;

struct Rot {
  double R[9];
  double dR[3][9];  // dR/d(rx), dR/d(ry), dR/d(rz)
};

// R = Rz(rz) Ry(ry) Rx(rx) and its three partial derivatives.
inline Rot rotation(const double *r) {
  const double cx = std::cos(r[0]), sx = std::sin(r[0]);
  const double cy = std::cos(r[1]), sy = std::sin(r[1]);
  const double cz = std::cos(r[2]), sz = std::sin(r[2]);
  const double Rx[9] = {1, 0, 0, 0, cx, -sx, 0, sx, cx};
  const double Ry[9] = {cy, 0, sy, 0, 1, 0, -sy, 0, cy};
  const double Rz[9] = {cz, -sz, 0, sz, cz, 0, 0, 0, 1};
  const double dRx[9] = {0, 0, 0, 0, -sx, -cx, 0, cx, -sx};
  const double dRy[9] = {-sy, 0, cy, 0, 0, 0, -cy, 0, -sy};
  const double dRz[9] = {-sz, -cz, 0, cz, -sz, 0, 0, 0, 0};
  auto mul3 = [](const double *a, const double *b, const double *c, double *out) {
    double t[9];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) t[i * 3 + j] = a[i * 3] * b[j] + a[i * 3 + 1] * b[3 + j] + a[i * 3 + 2] * b[6 + j];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) out[i * 3 + j] = t[i * 3] * c[j] + t[i * 3 + 1] * c[3 + j] + t[i * 3 + 2] * c[6 + j];
  };
  Rot out;
  mul3(Rz, Ry, Rx, out.R);
  mul3(Rz, Ry, dRx, out.dR[0]);
  mul3(Rz, dRy, Rx, out.dR[1]);
  mul3(dRz, Ry, Rx, out.dR[2]);
  return out;
}

// x = pi(R X + t); A = dx/d(r, t) (2 x 6), B = dx/dX (2 x 3); A or B may be null.
inline void project(const double *a, const double *X, double *x, double *A, double *B) {
  const Rot rot = rotation(a);
  double Xc[3];
  for (int r = 0; r < 3; ++r) Xc[r] = rot.R[r * 3] * X[0] + rot.R[r * 3 + 1] * X[1] + rot.R[r * 3 + 2] * X[2] + a[3 + r];
  const double iz = 1.0 / Xc[2];
  x[0] = kFocal * Xc[0] * iz + kCx;
  x[1] = kFocal * Xc[1] * iz + kCy;
  // d x / d Xc
  const double P[2][3] = {{kFocal * iz, 0, -kFocal * Xc[0] * iz * iz}, {0, kFocal * iz, -kFocal * Xc[1] * iz * iz}};
  if (A) {
    for (int c = 0; c < 3; ++c) {
      double d[3];
      for (int r = 0; r < 3; ++r)
        d[r] = rot.dR[c][r * 3] * X[0] + rot.dR[c][r * 3 + 1] * X[1] + rot.dR[c][r * 3 + 2] * X[2];
      for (int q = 0; q < 2; ++q) A[q * 6 + c] = P[q][0] * d[0] + P[q][1] * d[1] + P[q][2] * d[2];
    }
    for (int c = 0; c < 3; ++c)
      for (int q = 0; q < 2; ++q) A[q * 6 + 3 + c] = P[q][c];
  }
  if (B)
    for (int q = 0; q < 2; ++q)
      for (int c = 0; c < 3; ++c)
        B[q * 3 + c] = P[q][0] * rot.R[c] + P[q][1] * rot.R[3 + c] + P[q][2] * rot.R[6 + c];
}

struct Problem {
  int n = 0, m = 0;
  std::vector<char> vmask;
  std::vector<double> truth;  // cameras then points
  std::vector<double> p0;     // perturbed start
  std::vector<double> x;      // measurements (noisy if asked)
  int nvis = 0;
  // Fixed parts for the motion-only / structure-only callbacks.
  const double *fixed_points = nullptr;  // n*3, for mot
  const double *fixed_cams = nullptr;    // m*6, for str

  double *cams(std::vector<double> &v) { return v.data(); }
  double *points(std::vector<double> &v) { return v.data() + m * kCnp; }
};

// n points, m cameras on an arc; each point is seen by each camera with probability `vis`
// (at least two cameras per point); noise sigma in pixels; start perturbed by `perturb`.
inline Problem make(int n, int m, double sigma, double perturb, unsigned seed, double vis = 0.7) {
  Problem pb;
  pb.n = n;
  pb.m = m;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0), U01(0.0, 1.0);
  std::normal_distribution<double> N(0.0, 1.0);
  pb.truth.resize(size_t(m) * kCnp + size_t(n) * kPnp);
  for (int j = 0; j < m; ++j) {
    double *a = pb.truth.data() + j * kCnp;
    a[0] = 0.05 * U(rng);
    a[1] = (m > 1 ? -0.6 + 1.2 * j / (m - 1) : 0.0);
    a[2] = 0.05 * U(rng);
    a[3] = 0.2 * U(rng);
    a[4] = 0.2 * U(rng);
    a[5] = 6.0 + 0.3 * U(rng);
  }
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) pb.truth[size_t(m) * kCnp + i * 3 + c] = U(rng);
  pb.vmask.assign(size_t(n) * m, 0);
  for (int i = 0; i < n; ++i) {
    int cnt = 0;
    for (int j = 0; j < m; ++j)
      if (U01(rng) < vis) pb.vmask[size_t(i) * m + j] = 1, ++cnt;
    for (int j = 0; cnt < 2 && j < m; ++j)
      if (!pb.vmask[size_t(i) * m + j]) pb.vmask[size_t(i) * m + j] = 1, ++cnt;
  }
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j)
      if (pb.vmask[size_t(i) * m + j]) {
        double xij[2];
        project(pb.truth.data() + j * kCnp, pb.truth.data() + size_t(m) * kCnp + i * 3, xij, nullptr, nullptr);
        pb.x.push_back(xij[0] + sigma * N(rng));
        pb.x.push_back(xij[1] + sigma * N(rng));
        ++pb.nvis;
      }
  pb.p0 = pb.truth;
  for (int j = 0; j < m; ++j)
    for (int c = 0; c < kCnp; ++c) pb.p0[j * kCnp + c] += perturb * (c < 3 ? 0.2 : 1.0) * U(rng);
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) pb.p0[size_t(m) * kCnp + i * 3 + c] += perturb * U(rng);
  return pb;
}

// ---- callbacks; adata is the Problem ----
inline const Problem &P(void *adata) { return *static_cast<const Problem *>(adata); }

// Expert, motion + structure.
inline void func_motstr(double *p, sba_crsm *idx, int *, int *, double *hx, void *adata) {
  const int m = idx->nc;
  for (int i = 0; i < idx->nr; ++i)
    for (int k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k)
      project(p + idx->colidx[k] * kCnp, p + m * kCnp + i * kPnp, hx + idx->val[k] * kMnp, nullptr, nullptr);
}
inline void fjac_motstr(double *p, sba_crsm *idx, int *, int *, double *jac, void *adata) {
  const int m = idx->nc;
  double x[2];
  for (int i = 0; i < idx->nr; ++i)
    for (int k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k) {
      double *blk = jac + idx->val[k] * (kMnp * (kCnp + kPnp));
      project(p + idx->colidx[k] * kCnp, p + m * kCnp + i * kPnp, x, blk, blk + kMnp * kCnp);
    }
}
// Expert, motion only: points fixed from the problem.
inline void func_mot(double *p, sba_crsm *idx, int *, int *, double *hx, void *adata) {
  for (int i = 0; i < idx->nr; ++i)
    for (int k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k)
      project(p + idx->colidx[k] * kCnp, P(adata).fixed_points + i * kPnp, hx + idx->val[k] * kMnp, nullptr, nullptr);
}
inline void fjac_mot(double *p, sba_crsm *idx, int *, int *, double *jac, void *adata) {
  double x[2];
  for (int i = 0; i < idx->nr; ++i)
    for (int k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k)
      project(p + idx->colidx[k] * kCnp, P(adata).fixed_points + i * kPnp, x, jac + idx->val[k] * kMnp * kCnp, nullptr);
}
// Expert, structure only: cameras fixed from the problem.
inline void func_str(double *p, sba_crsm *idx, int *, int *, double *hx, void *adata) {
  for (int i = 0; i < idx->nr; ++i)
    for (int k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k)
      project(P(adata).fixed_cams + idx->colidx[k] * kCnp, p + i * kPnp, hx + idx->val[k] * kMnp, nullptr, nullptr);
}
inline void fjac_str(double *p, sba_crsm *idx, int *, int *, double *jac, void *adata) {
  double x[2];
  for (int i = 0; i < idx->nr; ++i)
    for (int k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k)
      project(P(adata).fixed_cams + idx->colidx[k] * kCnp, p + i * kPnp, x, nullptr, jac + idx->val[k] * kMnp * kPnp);
}

// Simple drivers.
inline void proj_motstr(int, int, double *aj, double *bi, double *xij, void *) { project(aj, bi, xij, nullptr, nullptr); }
inline void projac_motstr(int, int, double *aj, double *bi, double *A, double *B, void *) {
  double x[2];
  project(aj, bi, x, A, B);
}
inline void proj_mot(int, int i, double *aj, double *xij, void *adata) {
  project(aj, P(adata).fixed_points + i * kPnp, xij, nullptr, nullptr);
}
inline void projac_mot(int, int i, double *aj, double *A, void *adata) {
  double x[2];
  project(aj, P(adata).fixed_points + i * kPnp, x, A, nullptr);
}
inline void proj_str(int j, int, double *bi, double *xij, void *adata) {
  project(P(adata).fixed_cams + j * kCnp, bi, xij, nullptr, nullptr);
}
inline void projac_str(int j, int, double *bi, double *B, void *adata) {
  double x[2];
  project(P(adata).fixed_cams + j * kCnp, bi, x, nullptr, B);
}

// Sum of squared reprojection errors of the motion+structure vector p.
inline double sq_error(const Problem &pb, const double *p) {
  double s = 0.0, x[2];
  int k = 0;
  for (int i = 0; i < pb.n; ++i)
    for (int j = 0; j < pb.m; ++j)
      if (pb.vmask[size_t(i) * pb.m + j]) {
        project(p + j * kCnp, p + pb.m * kCnp + i * kPnp, x, nullptr, nullptr);
        s += (x[0] - pb.x[2 * k]) * (x[0] - pb.x[2 * k]) + (x[1] - pb.x[2 * k + 1]) * (x[1] - pb.x[2 * k + 1]);
        ++k;
      }
  return s;
}

}  // namespace synth

#endif
