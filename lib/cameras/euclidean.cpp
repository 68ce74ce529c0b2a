// SPDX-License-Identifier: BSD-3-Clause
#include "cameras/euclidean.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <utility>

#include "cameras/euclidean_rotation.h"

namespace sbacameras::euclidean {

int camera_params(CameraKind kind) {
  switch (kind) {
    case CameraKind::FixedIntrinsics: return 6;
    case CameraKind::VaryingIntrinsics: return 11;
    case CameraKind::VaryingIntrinsicsDistortion: return 16;
  }
  return 0;
}

Quaternion multiply(const Quaternion &a, const Quaternion &b) {
  return {a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
          a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
          a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
          a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
}

Quaternion normalized_rotation(const Quaternion &q) {
  double sq = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
  Quaternion u = q;
  // The squares of components near 1e308 overflow and those of components near 1e-200
  // underflow: such a quaternion is first scaled by its largest component. One of ordinary
  // size is not, so that its rotation keeps the bits the plain formula gives it.
  if (!(sq >= 1e-200 && sq <= 1e200)) {
    const double big = std::max({std::fabs(q.w), std::fabs(q.x), std::fabs(q.y), std::fabs(q.z)});
    u = {q.w / big, q.x / big, q.y / big, q.z / big};
    sq = u.w * u.w + u.x * u.x + u.y * u.y + u.z * u.z;
  }
  const double s = (u.w < 0 ? -1.0 : 1.0) / std::sqrt(sq);
  return {u.w * s, u.x * s, u.y * s, u.z * s};
}

void rotation_matrix(const Quaternion &q, double R[9]) { sbaeuc_rotation_matrix(q.w, q.x, q.y, q.z, R); }

Quaternion quaternion_of(const double R[9]) {
  const double tr = R[0] + R[4] + R[8];
  Quaternion q;
  if (tr >= R[0] && tr >= R[4] && tr >= R[8]) {
    const double s = 2.0 * std::sqrt(1.0 + tr);  // 4w
    q = {0.25 * s, (R[7] - R[5]) / s, (R[2] - R[6]) / s, (R[3] - R[1]) / s};
  } else if (R[0] >= R[4] && R[0] >= R[8]) {
    const double s = 2.0 * std::sqrt(1.0 + R[0] - R[4] - R[8]);  // 4x
    q = {(R[7] - R[5]) / s, 0.25 * s, (R[1] + R[3]) / s, (R[2] + R[6]) / s};
  } else if (R[4] >= R[8]) {
    const double s = 2.0 * std::sqrt(1.0 + R[4] - R[0] - R[8]);  // 4y
    q = {(R[2] - R[6]) / s, (R[1] + R[3]) / s, 0.25 * s, (R[5] + R[7]) / s};
  } else {
    const double s = 2.0 * std::sqrt(1.0 + R[8] - R[0] - R[4]);  // 4z
    q = {(R[3] - R[1]) / s, (R[2] + R[6]) / s, (R[5] + R[7]) / s, 0.25 * s};
  }
  return normalized_rotation(q);
}


namespace {

// Where each block sits in a camera's parameter vector; -1 for a block the kind lacks.
template <CameraKind K>
struct Layout;
template <>
struct Layout<CameraKind::FixedIntrinsics> {
  static constexpr int intr = -1, dist = -1, rot = 0, trans = 3, cnp = 6;
};
template <>
struct Layout<CameraKind::VaryingIntrinsics> {
  static constexpr int intr = 0, dist = -1, rot = 5, trans = 8, cnp = 11;
};
template <>
struct Layout<CameraKind::VaryingIntrinsicsDistortion> {
  static constexpr int intr = 0, dist = 5, rot = 10, trans = 13, cnp = 16;
};

}  // namespace

// The projection of one point and its derivatives, specialised per camera kind so the block
// offsets and sizes are compile-time constants.
template <CameraKind K>
struct Kernel {
  using L = Layout<K>;
  static constexpr bool kHasIntrinsics = L::intr >= 0;
  static constexpr bool kHasDistortion = L::dist >= 0;

  // Everything about camera j that does not depend on the point: set up once per camera by
  // the whole-vector callbacks, rather than once per projection.
  struct Frame {
    int free_intr, free_dist;
    double in[kIntrinsicParams];   // fu u0 v0 ar s, held ones from the input camera
    double kc[kDistortionParams];  // likewise
    const double *R0;              // R(q0_j)
    sbaeuc_correction qs;          // the correction and its derivatives (euclidean_rotation.h)
    double M[9];                   // R(qs) R(q0_j): d X_c / d X
    const double *t;
    // d X_c / d v = sum_n X_n dRv[n] for the point X (3x3 each, row-major): X_c = R(qs) R(q0) X
    // + t is linear in X, so its derivative in the rotation parameter v is too, and the
    // per-point work is 27 multiply-adds. Worth it for a camera's many points (the whole-vector
    // callbacks); project_jacobian_at_point takes it at the point directly.
    bool has_dRv;
    double dRv[27];
  };

  static void prepare(const CameraModel &model, int j, const double *a, Frame *f, bool jacobian_tensor) {
    const Camera &cam0 = model.cameras0_[j];
    f->free_intr = kHasIntrinsics ? kIntrinsicParams - model.nccalib_ : 0;
    const double in0[kIntrinsicParams] = {cam0.k.fu, cam0.k.u0, cam0.k.v0, cam0.k.ar, cam0.k.s};
    for (int c = 0; c < kIntrinsicParams; ++c) f->in[c] = c < f->free_intr ? a[L::intr + c] : in0[c];
    f->free_dist = kHasDistortion ? kDistortionParams - model.ncdist_ : 0;
    for (int c = 0; c < kDistortionParams; ++c) f->kc[c] = c < f->free_dist ? a[L::dist + c] : cam0.kc[c];
    const double *R0 = f->R0 = model.R0_.data() + static_cast<std::size_t>(j) * 9;
    const sbaeuc_correction &qs = f->qs = sbaeuc_correction_of(a + L::rot);
    double Rs[9];
    rotation_matrix({qs.w, qs.u[0], qs.u[1], qs.u[2]}, Rs);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        f->M[r * 3 + c] = Rs[r * 3] * R0[c] + Rs[r * 3 + 1] * R0[3 + c] + Rs[r * 3 + 2] * R0[6 + c];
    f->t = a + L::trans;
    f->has_dRv = jacobian_tensor;
    if (jacobian_tensor)
      for (int n = 0; n < 3; ++n) {  // Y = R(q0) e_n: column n of R(q0)
        const double Y[3] = {R0[n], R0[3 + n], R0[6 + n]};
        sbaeuc_rotation_derivative(&qs, Y, f->dRv + 9 * n);
      }
  }

  // tensor: the rotation derivative through the per-camera tensor, as the whole-vector
  // callbacks take it (bit-identical to them); else directly at the point (cheaper for one).
  static void eval(const CameraModel &model, int j, const double *a, const double *b, double *x,
                   double *A, double *B, bool tensor) {
    Frame f;
    prepare(model, j, a, &f, tensor && A != nullptr);
    eval(f, b, x, A, B);
  }

  // The normalized point after distortion. Bouguet: x_d = (1 + kc0 r^2 + kc1 r^4 + kc4 r^6)
  // x_n + tangential terms (kc2, kc3); D = d(x_d, y_d) / d(x_n, y_n), r2 = r^2.
  static void distort(const double *kc, double xn, double yn, double *xd, double *yd, double D[4], double *r2) {
    *xd = xn;
    *yd = yn;
    D[0] = 1;
    D[1] = D[2] = 0;
    D[3] = 1;
    *r2 = 0;
    if constexpr (kHasDistortion) {
      const double q = *r2 = xn * xn + yn * yn;
      const double radial = 1 + q * (kc[0] + q * (kc[1] + q * kc[4]));
      const double dradial_dr2 = kc[0] + q * (2 * kc[1] + 3 * q * kc[4]);
      *xd = radial * xn + 2 * kc[2] * xn * yn + kc[3] * (q + 2 * xn * xn);
      *yd = radial * yn + kc[2] * (q + 2 * yn * yn) + 2 * kc[3] * xn * yn;
      D[0] = radial + 2 * xn * xn * dradial_dr2 + 2 * kc[2] * yn + 6 * kc[3] * xn;
      D[1] = 2 * xn * yn * dradial_dr2 + 2 * kc[2] * xn + 2 * kc[3] * yn;
      D[2] = 2 * xn * yn * dradial_dr2 + 2 * kc[2] * xn + 2 * kc[3] * yn;
      D[3] = radial + 2 * yn * yn * dradial_dr2 + 6 * kc[2] * yn + 2 * kc[3] * xn;
    }
  }

  // The camera rows A (2 x cnp) at point b: the intrinsics' and the distortion's (held ones
  // zero) from the distorted point (xd, yd), the pose's through H = d pixel / d X_c.
  static void camera_jacobian(const Frame &f, const double *b, double xn, double yn, double xd, double yd, double r2,
                              const double H[6], double *A) {
    const double fu = f.in[0], ar = f.in[3], sk = f.in[4], fv = fu * ar;
    constexpr int cnp = L::cnp;
    double *A0 = A, *A1 = A + cnp;
    if constexpr (kHasIntrinsics) {
      const double du[kIntrinsicParams] = {xd, 1, 0, 0, yd};
      const double dv[kIntrinsicParams] = {ar * yd, 0, 1, fu * yd, 0};
      for (int c = 0; c < kIntrinsicParams; ++c) {
        A0[L::intr + c] = c < f.free_intr ? du[c] : 0.0;
        A1[L::intr + c] = c < f.free_intr ? dv[c] : 0.0;
      }
    }
    if constexpr (kHasDistortion) {
      // d(x_d, y_d) / d kc, then through Kd.
      const double r4 = r2 * r2, xy2 = 2 * xn * yn;
      const double dx[kDistortionParams] = {r2 * xn, r4 * xn, xy2, r2 + 2 * xn * xn, r4 * r2 * xn};
      const double dy[kDistortionParams] = {r2 * yn, r4 * yn, r2 + 2 * yn * yn, xy2, r4 * r2 * yn};
      for (int c = 0; c < kDistortionParams; ++c) {
        const bool free = c < f.free_dist;
        A0[L::dist + c] = free ? fu * dx[c] + sk * dy[c] : 0.0;
        A1[L::dist + c] = free ? fv * dy[c] : 0.0;
      }
    }
    double Jv[9];
    if (f.has_dRv) {
      for (int e = 0; e < 9; ++e) Jv[e] = b[0] * f.dRv[e] + b[1] * f.dRv[9 + e] + b[2] * f.dRv[18 + e];
    } else {
      double Y[3];
      sbaeuc_mat3_vec(f.R0, b, Y);
      sbaeuc_rotation_derivative(&f.qs, Y, Jv);
    }
    for (int c = 0; c < 3; ++c) {
      A0[L::rot + c] = H[0] * Jv[c] + H[1] * Jv[3 + c] + H[2] * Jv[6 + c];
      A1[L::rot + c] = H[3] * Jv[c] + H[4] * Jv[3 + c] + H[5] * Jv[6 + c];
      A0[L::trans + c] = H[c];
      A1[L::trans + c] = H[3 + c];
    }
  }

  static void eval(const Frame &f, const double *b, double *x, double *A, double *B) {
    const double fu = f.in[0], u0 = f.in[1], v0 = f.in[2], ar = f.in[3], sk = f.in[4];
    const double *M = f.M;

    // X_c = R(qs) R(q0) X + t: the correction acts after the input rotation.
    double Xc[3];
    sbaeuc_mat3_vec(M, b, Xc);
    for (int r = 0; r < 3; ++r) Xc[r] += f.t[r];

    const double iz = 1.0 / Xc[2];
    const double xn = Xc[0] * iz, yn = Xc[1] * iz;
    double xd, yd, D[4], r2;
    distort(f.kc, xn, yn, &xd, &yd, D, &r2);

    const double fv = fu * ar;
    if (x) {
      x[0] = fu * xd + sk * yd + u0;
      x[1] = fv * yd + v0;
    }
    if (!A && !B) return;

    // Chain: pixel <- (x_d, y_d) by Kd = [fu s; 0 fv], <- (x_n, y_n) by D, <- X_c by P.
    const double G[4] = {fu * D[0] + sk * D[2], fu * D[1] + sk * D[3], fv * D[2], fv * D[3]};
    const double P[6] = {iz, 0, -xn * iz, 0, iz, -yn * iz};
    double H[6];  // d pixel / d X_c
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < 3; ++c) H[r * 3 + c] = G[r * 2] * P[c] + G[r * 2 + 1] * P[3 + c];

    if (B) {
      for (int r = 0; r < 2; ++r)
        for (int c = 0; c < 3; ++c)
          B[r * 3 + c] = H[r * 3] * M[c] + H[r * 3 + 1] * M[3 + c] + H[r * 3 + 2] * M[6 + c];
    }
    if (A) camera_jacobian(f, b, xn, yn, xd, yd, r2, H, A);
  }
};

CameraModel::CameraModel(CameraKind kind, const std::vector<Camera> &cameras,
                         std::vector<double> points, int nccalib, int ncdist)
    : kind_(kind),
      cnp_(camera_params(kind)),
      nccalib_(nccalib),
      ncdist_(ncdist),
      points0_(std::move(points)) {
  if (nccalib < 0 || nccalib > kIntrinsicParams)
    throw std::invalid_argument("nccalib must be between 0 and 5");
  if (ncdist < 0 || ncdist > kDistortionParams)
    throw std::invalid_argument("ncdist must be between 0 and 5");
  if (points0_.size() % kPointParams != 0)
    throw std::invalid_argument("point coordinates must come in threes");

  const std::size_t m = cameras.size();
  cameras0_.reserve(m);
  R0_.resize(m * 9);
  cams0_.assign(m * cnp_, 0.0);
  for (std::size_t j = 0; j < m; ++j) {
    Camera c = cameras[j];
    const Quaternion &q = c.q;
    if (q.w == 0 && q.x == 0 && q.y == 0 && q.z == 0)
      throw std::invalid_argument("camera " + std::to_string(j) + " has a zero quaternion");
    c.q = normalized_rotation(q);
    rotation_matrix(c.q, &R0_[j * 9]);

    // v = 0 (the zero-initialised rotation block): every camera starts at its input rotation.
    double *a = &cams0_[j * cnp_];
    const int intr = kind == CameraKind::FixedIntrinsics ? -1 : 0;
    const int dist = kind == CameraKind::VaryingIntrinsicsDistortion ? 5 : -1;
    if (intr >= 0) {
      a[0] = c.k.fu;
      a[1] = c.k.u0;
      a[2] = c.k.v0;
      a[3] = c.k.ar;
      a[4] = c.k.s;
    }
    if (dist >= 0)
      for (int i = 0; i < kDistortionParams; ++i) a[dist + i] = c.kc[i];
    for (int i = 0; i < 3; ++i) a[cnp_ - 3 + i] = c.t[i];
    cameras0_.push_back(c);
  }
}

Camera CameraModel::camera(int j, const double *a) const {
  Camera c = cameras0_[j];
  const int rot = cnp_ - 6;
  if (kind_ != CameraKind::FixedIntrinsics) {
    const int free_intr = kIntrinsicParams - nccalib_;
    double *k[kIntrinsicParams] = {&c.k.fu, &c.k.u0, &c.k.v0, &c.k.ar, &c.k.s};
    for (int i = 0; i < free_intr; ++i) *k[i] = a[i];
  }
  if (kind_ == CameraKind::VaryingIntrinsicsDistortion)
    for (int i = 0; i < kDistortionParams - ncdist_; ++i) c.kc[i] = a[kIntrinsicParams + i];
  const sbaeuc_correction qs = sbaeuc_correction_of(a + rot);
  c.q = normalized_rotation(multiply({qs.w, qs.u[0], qs.u[1], qs.u[2]}, cameras0_[j].q));
  for (int i = 0; i < 3; ++i) c.t[i] = a[rot + 3 + i];
  return c;
}

namespace {

// One projection by the kernel of the model's kind (tensor: see Kernel::eval).
void eval_one(const CameraModel &model, int j, const double *a, const double *b, double *x, double *A,
              double *B, bool tensor) {
  switch (model.kind()) {
    case CameraKind::FixedIntrinsics:
      return Kernel<CameraKind::FixedIntrinsics>::eval(model, j, a, b, x, A, B, tensor);
    case CameraKind::VaryingIntrinsics:
      return Kernel<CameraKind::VaryingIntrinsics>::eval(model, j, a, b, x, A, B, tensor);
    case CameraKind::VaryingIntrinsicsDistortion:
      return Kernel<CameraKind::VaryingIntrinsicsDistortion>::eval(model, j, a, b, x, A, B, tensor);
  }
}

}  // namespace

void CameraModel::project_jacobian(int j, const double *a, const double *b, double *x, double *A,
                                   double *B) const {
  eval_one(*this, j, a, b, x, A, B, true);
}

void CameraModel::project_jacobian_at_point(int j, const double *a, const double *b, double *x,
                                            double *A, double *B) const {
  eval_one(*this, j, a, b, x, A, B, false);
}

void CameraModel::project(int j, const double *a, const double *b, double x[2]) const {
  project_jacobian(j, a, b, x, nullptr, nullptr);
}

// ---- callbacks ----

namespace {

const CameraModel &model_of(void *adata) { return *static_cast<const CameraModel *>(adata); }

// Calls f(i, j, k) for every visible projection: point i, camera j, measurement ordinal k.
template <typename F>
void for_each_projection(const sba_crsm &idx, F &&f) {
  for (int i = 0; i < idx.nr; ++i)
    for (int e = idx.rowptr[i]; e < idx.rowptr[i + 1]; ++e) f(i, idx.colidx[e], idx.val[e]);
}

// Offsets into p and into the outputs in std::size_t: nvis * block can outgrow int.
inline std::size_t off(int index, int stride) {
  return static_cast<std::size_t>(index) * static_cast<std::size_t>(stride);
}

template <CameraKind K>
struct Callbacks {
  using Kern = Kernel<K>;
  static constexpr int cnp = Layout<K>::cnp;
  static constexpr int mnp = kMeasurementParams, pnp = kPointParams;

  // The whole-vector callbacks see every camera's parameters at once: the per-camera part of
  // the projection (intrinsics, the rotation and its derivatives) is set up once per camera,
  // not once per projection.
  static std::vector<typename Kern::Frame> frames(const CameraModel &model, const double *pa, bool jacobian) {
    std::vector<typename Kern::Frame> f(static_cast<std::size_t>(model.ncameras()));
    for (int j = 0; j < model.ncameras(); ++j)
      Kern::prepare(model, j, pa + off(j, cnp), &f[size_t(j)], jacobian);
    return f;
  }

  // ---- expert: p = cameras then points ----
  static void motstr_func(double *p, sba_crsm *idx, int *, int *, double *hx, void *adata) {
    const CameraModel &model = model_of(adata);
    const double *pb = p + off(model.ncameras(), cnp);
    const auto f = frames(model, p, false);
    for_each_projection(*idx, [&](int i, int j, int k) {
      Kern::eval(f[size_t(j)], pb + off(i, pnp), hx + off(k, mnp), nullptr, nullptr);
    });
  }
  static void motstr_fjac(double *p, sba_crsm *idx, int *, int *, double *jac, void *adata) {
    const CameraModel &model = model_of(adata);
    const double *pb = p + off(model.ncameras(), cnp);
    constexpr int block = mnp * (cnp + pnp);
    const auto f = frames(model, p, true);
    for_each_projection(*idx, [&](int i, int j, int k) {
      double *A = jac + off(k, block);
      Kern::eval(f[size_t(j)], pb + off(i, pnp), nullptr, A, A + mnp * cnp);
    });
  }

  // ---- expert: p = cameras, points from the model ----
  static void mot_func(double *p, sba_crsm *idx, int *, int *, double *hx, void *adata) {
    const CameraModel &model = model_of(adata);
    const auto f = frames(model, p, false);
    for_each_projection(*idx, [&](int i, int j, int k) {
      Kern::eval(f[size_t(j)], model.initial_point(i), hx + off(k, mnp), nullptr, nullptr);
    });
  }
  static void mot_fjac(double *p, sba_crsm *idx, int *, int *, double *jac, void *adata) {
    const CameraModel &model = model_of(adata);
    const auto f = frames(model, p, true);
    for_each_projection(*idx, [&](int i, int j, int k) {
      Kern::eval(f[size_t(j)], model.initial_point(i), nullptr, jac + off(k, mnp * cnp), nullptr);
    });
  }

  // ---- expert: p = points, cameras from the model ----
  static void str_func(double *p, sba_crsm *idx, int *, int *, double *hx, void *adata) {
    const CameraModel &model = model_of(adata);
    for_each_projection(*idx, [&](int i, int j, int k) {
      Kern::eval(model, j, model.initial_camera(j), p + off(i, pnp), hx + off(k, mnp), nullptr,
                 nullptr, true);
    });
  }
  static void str_fjac(double *p, sba_crsm *idx, int *, int *, double *jac, void *adata) {
    const CameraModel &model = model_of(adata);
    for_each_projection(*idx, [&](int i, int j, int k) {
      Kern::eval(model, j, model.initial_camera(j), p + off(i, pnp), nullptr, nullptr,
                 jac + off(k, mnp * pnp), true);
    });
  }

  // ---- simple drivers ----
  static void motstr_proj(int j, int, double *aj, double *bi, double *xij, void *adata) {
    Kern::eval(model_of(adata), j, aj, bi, xij, nullptr, nullptr, true);
  }
  static void motstr_projac(int j, int, double *aj, double *bi, double *Aij, double *Bij,
                            void *adata) {
    Kern::eval(model_of(adata), j, aj, bi, nullptr, Aij, Bij, true);
  }
  static void mot_proj(int j, int i, double *aj, double *xij, void *adata) {
    const CameraModel &model = model_of(adata);
    Kern::eval(model, j, aj, model.initial_point(i), xij, nullptr, nullptr, true);
  }
  static void mot_projac(int j, int i, double *aj, double *Aij, void *adata) {
    const CameraModel &model = model_of(adata);
    Kern::eval(model, j, aj, model.initial_point(i), nullptr, Aij, nullptr, true);
  }
  static void str_proj(int j, int, double *bi, double *xij, void *adata) {
    const CameraModel &model = model_of(adata);
    Kern::eval(model, j, model.initial_camera(j), bi, xij, nullptr, nullptr, true);
  }
  static void str_projac(int j, int, double *bi, double *Bij, void *adata) {
    const CameraModel &model = model_of(adata);
    Kern::eval(model, j, model.initial_camera(j), bi, nullptr, nullptr, Bij, true);
  }

  static ExpertCallbacks expert(Refinement refinement) {
    switch (refinement) {
      case Refinement::MotionStructure: return {motstr_func, motstr_fjac};
      case Refinement::Motion: return {mot_func, mot_fjac};
      case Refinement::Structure: return {str_func, str_fjac};
    }
    return {nullptr, nullptr};
  }
};

// Picks Callbacks<K>::what for the run-time kind.
template <typename Pick>
auto by_kind(CameraKind kind, Pick pick) {
  switch (kind) {
    case CameraKind::VaryingIntrinsics: return pick(Callbacks<CameraKind::VaryingIntrinsics>{});
    case CameraKind::VaryingIntrinsicsDistortion:
      return pick(Callbacks<CameraKind::VaryingIntrinsicsDistortion>{});
    case CameraKind::FixedIntrinsics: break;
  }
  return pick(Callbacks<CameraKind::FixedIntrinsics>{});
}

}  // namespace

ExpertCallbacks expert_callbacks(CameraKind kind, Refinement refinement) {
  return by_kind(kind, [&](auto cb) { return decltype(cb)::expert(refinement); });
}

MotStrCallbacks motstr_callbacks(CameraKind kind) {
  return by_kind(kind, [](auto cb) {
    using C = decltype(cb);
    return MotStrCallbacks{C::motstr_proj, C::motstr_projac};
  });
}

MotCallbacks mot_callbacks(CameraKind kind) {
  return by_kind(kind, [](auto cb) {
    using C = decltype(cb);
    return MotCallbacks{C::mot_proj, C::mot_projac};
  });
}

StrCallbacks str_callbacks(CameraKind kind) {
  return by_kind(kind, [](auto cb) {
    using C = decltype(cb);
    return StrCallbacks{C::str_proj, C::str_projac};
  });
}

}  // namespace sbacameras::euclidean
