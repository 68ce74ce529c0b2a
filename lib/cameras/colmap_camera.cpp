// SPDX-License-Identifier: BSD-3-Clause
#include "cameras/colmap_camera.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>

#include "cameras/camera_pose.h"
#include "cameras/euclidean_rotation.h"
#include "cameras/rigid_pose.h"

namespace sbacameras::colmap_camera {

namespace {

bool known(int model) { return model >= 0 && model < kNumModels; }

// g(s) = atan(r) / r with s = r^2, and dg/ds. The closed form of dg/ds cancels as s -> 0,
// and g itself is 0/0 at s = 0: below the threshold the series, whose first omitted term
// (s^5 / 11) is far below a double's resolution there.
void atan_ratio(double s, double *g, double *dg) {
  if (s < 1e-4) {
    *g = 1 + s * (-1.0 / 3 + s * (1.0 / 5 + s * (-1.0 / 7 + s / 9)));
    *dg = -1.0 / 3 + s * (2.0 / 5 + s * (-3.0 / 7 + s * 4.0 / 9));
    return;
  }
  const double r = std::sqrt(s);
  *g = std::atan(r) / r;
  *dg = (1 / (1 + s) - *g) / (2 * s);
}

// The distortion (u, v) -> (ud, vd) of a model: D = d(ud, vd)/d(u, v) (2x2 row-major) and the
// derivatives in the extra parameters, Eu[k] = d ud / d extra_k, Ev[k] likewise.
struct Distortion {
  double ud, vd;
  double D[4];
  double Eu[kMaxParams], Ev[kMaxParams];
};

// The polynomial-radial, tangential and thin-prism family (SIMPLE_RADIAL, RADIAL, OPENCV,
// FULL_OPENCV and the second stage of THIN_PRISM_FISHEYE and RAD_TAN_THIN_PRISM_FISHEYE): with
// s = x^2 + y^2,
//   R = (1 + n1 s + n2 s^2 + n3 s^3 + n4 s^4) / (1 + d1 s + d2 s^2 + d3 s^3),
//   xd = x R + 2 p1 x y + p2 (s + 2 x^2) + sx s + sx2 s^2,
//   yd = y R + p1 (s + 2 y^2) + 2 p2 x y + sy s + sy2 s^2.
// A model names which of these terms its extra parameters are (the rest are zero).
enum Role { N1, N2, N3, N4, D1, D2, D3, P1, P2, SX, SY, SX2, SY2, kRoles };

// kRational: the model has denominator terms (FULL_OPENCV's). Without them Dn is 1 and dDn 0,
// and R, dR/ds and the numerator's derivatives are taken as N, dN and x s^i, the values the
// quotients give, without the divisions: this runs for every observation at every evaluation.
// kDerivatives false: (ud, vd) alone, the same values, for an evaluation of the residuals.
template <bool kRational, bool kDerivatives = true>
void radtan(const int *roles, int ne, const double *extra, double x, double y, Distortion *out) {
  double c[kRoles] = {};
  for (int k = 0; k < ne; ++k) c[roles[k]] = extra[k];
  const double s = x * x + y * y;
  const double N = 1 + s * (c[N1] + s * (c[N2] + s * (c[N3] + s * c[N4])));
  const double dN = c[N1] + s * (2 * c[N2] + s * (3 * c[N3] + s * 4 * c[N4]));
  const double Dn = kRational ? 1 + s * (c[D1] + s * (c[D2] + s * c[D3])) : 1.0;
  const double dDn = c[D1] + s * (2 * c[D2] + s * 3 * c[D3]);
  const double R = kRational ? N / Dn : N;
  const double dR = kRational ? (dN * Dn - N * dDn) / (Dn * Dn) : dN;  // dR/ds
  const double p1 = c[P1], p2 = c[P2];
  // The thin prism's terms sx s + sx2 s^2 (and sy's) and their derivatives in s.
  const double tx = s * (c[SX] + s * c[SX2]), ty = s * (c[SY] + s * c[SY2]);
  const double dtx = c[SX] + 2 * s * c[SX2], dty = c[SY] + 2 * s * c[SY2];
  const double xy = x * y;
  out->ud = x * R + 2 * p1 * xy + p2 * (s + 2 * x * x) + tx;
  out->vd = y * R + p1 * (s + 2 * y * y) + 2 * p2 * xy + ty;
  if (!kDerivatives) return;
  out->D[0] = R + 2 * x * x * dR + 2 * p1 * y + 6 * p2 * x + 2 * dtx * x;
  out->D[1] = 2 * xy * dR + 2 * p1 * x + 2 * p2 * y + 2 * dtx * y;
  out->D[2] = 2 * xy * dR + 2 * p1 * x + 2 * p2 * y + 2 * dty * x;
  out->D[3] = R + 2 * y * y * dR + 6 * p1 * y + 2 * p2 * x + 2 * dty * y;
  double du[kRoles] = {}, dv[kRoles] = {};
  double si = 1;
  for (int i = 0; i < 4; ++i) {  // dR/dn_i = s^i / Dn
    si *= s;
    du[N1 + i] = kRational ? x * si / Dn : x * si;
    dv[N1 + i] = kRational ? y * si / Dn : y * si;
  }
  si = 1;
  for (int i = 0; kRational && i < 3; ++i) {  // dR/dd_i = -N s^i / Dn^2
    si *= s;
    du[D1 + i] = -x * N * si / (Dn * Dn);
    dv[D1 + i] = -y * N * si / (Dn * Dn);
  }
  du[P1] = 2 * xy;
  dv[P1] = s + 2 * y * y;
  du[P2] = s + 2 * x * x;
  dv[P2] = 2 * xy;
  du[SX] = s;
  dv[SY] = s;
  du[SX2] = s * s;
  dv[SY2] = s * s;
  for (int k = 0; k < ne; ++k) {
    out->Eu[k] = du[roles[k]];
    out->Ev[k] = dv[roles[k]];
  }
}

// radtan for SIMPLE_RADIAL and RADIAL (ne 1: k1; 2: k1, k2), the terms that are not zero
// written out: each value is radtan's, whose other terms add zeros (a zero's sign aside), and
// these two are the most common COLMAP models, projected for every observation at every
// evaluation.
template <bool kDerivatives>
inline __attribute__((always_inline)) void radial(int ne, const double *k, double x, double y, Distortion *out) {
  const double s = x * x + y * y;
  const double R = ne > 1 ? 1 + s * (k[0] + s * k[1]) : 1 + s * k[0];
  out->ud = x * R;
  out->vd = y * R;
  if (!kDerivatives) return;
  const double dR = ne > 1 ? k[0] + s * (2 * k[1]) : k[0];  // dR/ds
  const double xy = x * y;
  out->D[0] = R + 2 * x * x * dR;
  out->D[1] = out->D[2] = 2 * xy * dR;
  out->D[3] = R + 2 * y * y * dR;
  out->Eu[0] = x * s;
  out->Ev[0] = y * s;
  if (ne > 1) {
    out->Eu[1] = x * (s * s);
    out->Ev[1] = y * (s * s);
  }
}

// (ud, vd) = (u, v) F(s), s = u^2 + v^2, and its derivatives in u and v; Fs = dF/ds.
void scale_radially(double u, double v, double F, double Fs, Distortion *out) {
  out->ud = u * F;
  out->vd = v * F;
  out->D[0] = F + 2 * u * u * Fs;
  out->D[1] = 2 * u * v * Fs;
  out->D[2] = out->D[1];
  out->D[3] = F + 2 * v * v * Fs;
}

// The fisheye family with a polynomial in theta (OPENCV_FISHEYE, SIMPLE_RADIAL_FISHEYE,
// RADIAL_FISHEYE, the first stage of RAD_TAN_THIN_PRISM_FISHEYE; with no coefficient, the
// equidistant SIMPLE_FISHEYE, FISHEYE and THIN_PRISM_FISHEYE's first stage):
// ud = u h(s), h = g(s) P(t), t = theta^2 = s g(s)^2, P = 1 + k1 t + k2 t^2 + ... (ne coefficients).
void fisheye(int ne, const double *k, double u, double v, Distortion *out) {
  const double s = u * u + v * v;
  double g, dg;
  atan_ratio(s, &g, &dg);
  const double t = s * g * g;
  const double dt = g * g + 2 * s * g * dg;  // dt/ds
  double P = 0, dP = 0;                      // Horner, from the highest power
  for (int i = ne - 1; i >= 0; --i) {
    dP = dP * t + (i + 1) * k[i];
    P = P * t + k[i];
  }
  P = 1 + t * P;
  const double h = g * P;
  const double dh = dg * P + g * dP * dt;
  scale_radially(u, v, h, dh, out);
  double ti = 1;
  for (int i = 0; i < ne; ++i) {
    ti *= t;
    out->Eu[i] = u * g * ti;
    out->Ev[i] = v * g * ti;
  }
}

// FOV: ud = u F, F = atan(c r) / (omega r), c = 2 tan(omega / 2), written F = q g(s c^2) with
// q = c / omega, so that omega -> 0 (q -> 1, a pinhole) and r -> 0 need no special case but
// q's series near omega = 0.
void fov(double omega, double u, double v, Distortion *out) {
  const double s = u * u + v * v;
  const double c = 2 * std::tan(omega / 2);
  const double dc = 1 + c * c / 4;  // dc/domega
  double q, dq;
  if (std::fabs(omega) < 1e-3) {
    const double w2 = omega * omega;
    q = 1 + w2 * (1.0 / 12 + w2 * (1.0 / 120 + w2 * 17.0 / 20160));
    dq = omega * (1.0 / 6 + w2 * (1.0 / 30 + w2 * 17.0 / 3360));
  } else {
    q = c / omega;
    dq = (dc * omega - c) / (omega * omega);
  }
  double g, dg;
  atan_ratio(s * c * c, &g, &dg);
  const double F = q * g;
  const double Fs = q * dg * c * c;
  const double Fw = dq * g + q * dg * s * 2 * c * dc;
  scale_radially(u, v, F, Fs, out);
  out->Eu[0] = u * Fw;
  out->Ev[0] = v * Fw;
}

// A second stage, radtan with ne parameters `extra`, applied to the result of a first one
// whose derivatives are those of its nfirst extra parameters (which come first in the
// model's list): the derivatives chained through the second stage.
void then_radtan(const int *roles, int ne, const double *extra, int nfirst, Distortion *d) {
  Distortion s;
  radtan<false>(roles, ne, extra, d->ud, d->vd, &s);
  const double *A = s.D, *B = d->D;
  Distortion out;
  out.ud = s.ud;
  out.vd = s.vd;
  out.D[0] = A[0] * B[0] + A[1] * B[2];
  out.D[1] = A[0] * B[1] + A[1] * B[3];
  out.D[2] = A[2] * B[0] + A[3] * B[2];
  out.D[3] = A[2] * B[1] + A[3] * B[3];
  for (int k = 0; k < nfirst; ++k) {
    out.Eu[k] = A[0] * d->Eu[k] + A[1] * d->Ev[k];
    out.Ev[k] = A[2] * d->Eu[k] + A[3] * d->Ev[k];
  }
  std::copy(s.Eu, s.Eu + ne, out.Eu + nfirst);
  std::copy(s.Ev, s.Ev + ne, out.Ev + nfirst);
  *d = out;
}

// THIN_PRISM_FISHEYE: the equidistant mapping (uf, vf) = (u, v) g(s), then radtan on it.
void thin_prism(const double *extra, double u, double v, Distortion *out) {
  static constexpr int kRolesThin[8] = {N1, N2, P1, P2, N3, N4, SX, SY};
  fisheye(0, nullptr, u, v, out);
  then_radtan(kRolesThin, 8, extra, 0, out);
}

// RAD_TAN_THIN_PRISM_FISHEYE: the fisheye polynomial of k0..k5, then the tangential and
// thin-prism terms of p0 p1 s0 s1 s2 s3 on its result.
void rad_tan_thin_prism(const double *extra, double u, double v, Distortion *out) {
  static constexpr int kRolesRadTan[6] = {P2, P1, SX, SX2, SY, SY2};
  fisheye(6, extra, u, v, out);
  then_radtan(kRolesRadTan, 6, extra + 6, 6, out);
}

// The polynomial models' distortion; false for another model.
template <bool kDerivatives>
inline __attribute__((always_inline)) bool polynomial(int model, const double *extra, double u, double v,
                                                      Distortion *out) {
  static constexpr int kRolesOpenCV[4] = {N1, N2, P1, P2};
  static constexpr int kRolesFull[8] = {N1, N2, P1, P2, N3, D1, D2, D3};
  switch (model) {
    case kSimpleRadial: return radial<kDerivatives>(1, extra, u, v, out), true;
    case kRadial: return radial<kDerivatives>(2, extra, u, v, out), true;
    case kOpenCV: return radtan<false, kDerivatives>(kRolesOpenCV, 4, extra, u, v, out), true;
    case kFullOpenCV: return radtan<true, kDerivatives>(kRolesFull, 8, extra, u, v, out), true;
    default: return false;
  }
}

// derivatives false: only (ud, vd) are wanted; the polynomial models then form nothing else.
inline __attribute__((always_inline)) void distort(int model, const double *extra, double u, double v,
                                                   Distortion *out, bool derivatives) {
  if (derivatives ? polynomial<true>(model, extra, u, v, out) : polynomial<false>(model, extra, u, v, out))
    return;
  switch (model) {
    case kOpenCVFisheye: return fisheye(4, extra, u, v, out);
    case kSimpleRadialFisheye: return fisheye(1, extra, u, v, out);
    case kRadialFisheye: return fisheye(2, extra, u, v, out);
    case kFov: return fov(extra[0], u, v, out);
    case kThinPrismFisheye: return thin_prism(extra, u, v, out);
    case kRadTanThinPrismFisheye: return rad_tan_thin_prism(extra, u, v, out);
    case kSimpleFisheye: case kFisheye: return fisheye(0, nullptr, u, v, out);
    default:  // the pinholes
      out->ud = u;
      out->vd = v;
      out->D[0] = out->D[3] = 1;
      out->D[1] = out->D[2] = 0;
  }
}

// The models that are functions of the camera-frame point itself (colmap_camera.h): (ud, vd)
// and J = d(ud, vd)/dXc (2x3 row-major) in place of Distortion's D.

// (ud, vd) = q (X, Y), with dq = dq/dXc and dqe[k] = dq/d extra_k (ne of them).
void scaled_point(const double *X, double q, const double dq[3], const double *dqe, int ne, Distortion *d,
                  double *J) {
  d->ud = q * X[0];
  d->vd = q * X[1];
  for (int r = 0; r < 2; ++r)
    for (int col = 0; col < 3; ++col) J[r * 3 + col] = X[r] * dq[col] + (r == col ? q : 0.0);
  for (int k = 0; k < ne; ++k) {
    d->Eu[k] = X[0] * dqe[k];
    d->Ev[k] = X[1] * dqe[k];
  }
}

// SIMPLE_DIVISION, DIVISION: (ud, vd) = q (X, Y), q = 2 / (Z + S), S = sqrt(Z^2 - 4 k rho). This
// form of the root has no cancellation in front of the camera, and is the pinhole at k = 0.
void division(double k, const double *X, Distortion *d, double *J) {
  const double rho = X[0] * X[0] + X[1] * X[1];
  const double S = std::sqrt(X[2] * X[2] - 4 * k * rho);
  const double q = 2 / (X[2] + S);
  const double c = -q * q / 2;  // dq / d(Z + S)
  const double dq[3] = {c * -4 * k * X[0] / S, c * -4 * k * X[1] / S, c * (1 + X[2] / S)};
  const double dqk = c * -2 * rho / S;
  scaled_point(X, q, dq, &dqk, 1, d, J);
}

// EUCM: (ud, vd) = q (X, Y), q = 1 / (alpha e + (1 - alpha) Z), e = sqrt(beta rho + Z^2).
void eucm(const double *extra, const double *X, Distortion *d, double *J) {
  const double alpha = extra[0], beta = extra[1];
  const double rho = X[0] * X[0] + X[1] * X[1];
  const double e = std::sqrt(beta * rho + X[2] * X[2]);
  const double q = 1 / (alpha * e + (1 - alpha) * X[2]);
  const double c = -q * q;  // dq / d(the denominator)
  const double dq[3] = {c * alpha * beta * X[0] / e, c * alpha * beta * X[1] / e,
                        c * (alpha * X[2] / e + 1 - alpha)};
  const double dqe[2] = {c * (e - X[2]), c * alpha * rho / (2 * e)};  // in alpha, beta
  scaled_point(X, q, dq, dqe, 2, d, J);
}

// EQUIRECTANGULAR: (ud, vd) = (longitude, latitude) = (atan2(X, Z), atan2(Y, sqrt(X^2 + Z^2))).
void equirectangular(const double *X, Distortion *d, double *J) {
  const double q2 = X[0] * X[0] + X[2] * X[2], q = std::sqrt(q2), n2 = q2 + X[1] * X[1];
  d->ud = std::atan2(X[0], X[2]);
  d->vd = std::atan2(X[1], q);
  J[0] = X[2] / q2;
  J[1] = 0;
  J[2] = -X[0] / q2;
  J[3] = -X[1] * X[0] / (n2 * q);
  J[4] = q / n2;
  J[5] = -X[1] * X[2] / (n2 * q);
}

// (ud, vd) of the camera-frame point Xc through a model's extra parameters, with (derivatives)
// J = d(ud, vd)/dXc and the derivatives in the extra parameters.
inline __attribute__((always_inline)) void map_point(int model, const double *extra, const double Xc[3],
                                                     Distortion *d, double J[6], bool derivatives) {
  switch (model) {
    case kSimpleDivision: case kDivision: return division(extra[0], Xc, d, J);
    case kEucm: return eucm(extra, Xc, d, J);
    case kEquirectangular: return equirectangular(Xc, d, J);
    default: break;
  }
  // (u, v) = (X, Y) / Z, then the distortion in the image plane.
  const double iz = 1 / Xc[2];
  const double u = Xc[0] * iz, v = Xc[1] * iz;
  distort(model, extra, u, v, d, derivatives);
  if (!derivatives) return;
  const double P[6] = {iz, 0, -u * iz, 0, iz, -v * iz};
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) J[r * 3 + c] = d->D[r * 2] * P[c] + d->D[r * 2 + 1] * P[3 + c];
}

constexpr double kPi = 3.14159265358979323846;

}  // namespace

const char *model_name(int model) { return known(model) ? kModels[model].name : nullptr; }
int param_count(int model) { return known(model) ? kModels[model].params : 0; }
int focal_count(int model) { return known(model) ? kModels[model].focals : 0; }

namespace {

// cnp rounded up to the next size the library has fixed-size kernels for (src/kernels.h).
int padded(int cnp) {
  for (int fast : {9, 11, 16})
    if (cnp <= fast) return fast;
  return cnp;
}

}  // namespace

int camera_params(int max_params) { return padded(kPoseParams + max_params); }
int rig_camera_params(int max_params) { return padded(kRigPoseParams + max_params); }

ParamKind param_kind(int model, int k) {
  if (model == kEquirectangular) return ParamKind::Size;
  const int nf = focal_count(model);
  if (k < nf) return ParamKind::Focal;
  if (k < nf + 2) return ParamKind::Principal;
  return ParamKind::Extra;
}

namespace {

// project's body, inlined where the model is a constant (eval_as), so that the model's
// branches, its table's counts and the loops over its parameters are resolved as it compiles.
// Inlined so, GCC sees d.Eu read under Jp and written under Jp || Jx, and warns that it may be
// read unset: Jp implies the derivatives, which write every Eu and Ev the model has.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
inline __attribute__((always_inline)) void project_model(int model, const double *params, const double Xc[3],
                                                         double x[2], double *Jp, double *Jx) {
  const int nf = kModels[model].focals, np = kModels[model].params;
  const bool panorama = model == kEquirectangular;
  // x = fx ud + cx, y = fy vd + cy: the panorama's scales and centre are its size's.
  const double fx = panorama ? params[0] / (2 * kPi) : params[0];
  const double fy = panorama ? params[1] / kPi : params[nf - 1];
  const double cx = panorama ? params[0] / 2 : params[nf];
  const double cy = panorama ? params[1] / 2 : params[nf + 1];
  // Not value-initialized: every mapping writes what is read of it (ud and vd; D or J with
  // derivatives; Eu and Ev for the model's extra parameters), and zeroing the whole struct
  // for every projection costs more than some models' arithmetic.
  Distortion d;
  double J[6];  // d(ud, vd)/dXc
  map_point(model, params + nf + 2, Xc, &d, J, Jp || Jx);
  if (x) {
    x[0] = fx * d.ud + cx;
    x[1] = fy * d.vd + cy;
  }
  if (Jp) {
    double *J0 = Jp, *J1 = Jp + np;
    std::fill(Jp, Jp + 2 * np, 0.0);
    if (panorama) {
      J0[0] = d.ud / (2 * kPi) + 0.5;
      J1[1] = d.vd / kPi + 0.5;
    } else {
      J0[0] = d.ud;
      J1[nf - 1] = d.vd;
      J0[nf] = 1;
      J1[nf + 1] = 1;
    }
    for (int k = nf + 2; k < np; ++k) {
      J0[k] = fx * d.Eu[k - nf - 2];
      J1[k] = fy * d.Ev[k - nf - 2];
    }
  }
  if (Jx)  // pixel <- (ud, vd) by diag(fx, fy), <- Xc by J
    for (int c = 0; c < 3; ++c) {
      Jx[c] = fx * J[c];
      Jx[3 + c] = fy * J[3 + c];
    }
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

}  // namespace

void project(int model, const double *params, const double Xc[3], double x[2], double *Jp, double *Jx) {
  project_model(model, params, Xc, x, Jp, Jx);
}

// ---- the sba camera models ----

namespace {

// The parameter count of camera j's model: throws for an unknown model or a count that is not
// the model's.
int checked_param_count(std::size_t j, int model, std::size_t count) {
  if (!known(model))
    throw std::invalid_argument("camera " + std::to_string(j) + ": unknown camera model id " + std::to_string(model));
  if (static_cast<int>(count) != param_count(model))
    throw std::invalid_argument("camera " + std::to_string(j) + ": " + model_name(model) + " takes " +
                                std::to_string(param_count(model)) + " parameters");
  return param_count(model);
}

// q as a unit rotation with w >= 0, and R(q) into R: throws for the zero quaternion.
euclidean::Quaternion unit_rotation(std::size_t j, const euclidean::Quaternion &q, double *R) {
  if (q.w == 0 && q.x == 0 && q.y == 0 && q.z == 0)
    throw std::invalid_argument("camera " + std::to_string(j) + " has a zero quaternion");
  const euclidean::Quaternion u = euclidean::normalized_rotation(q);
  euclidean::rotation_matrix(u, R);
  return u;
}

// The rotation qs(v) q0 of the local parametrization, unit with w >= 0.
euclidean::Quaternion corrected(const double v[3], const euclidean::Quaternion &q0) {
  const sbaeuc_correction qs = sbaeuc_correction_of(v);
  return euclidean::normalized_rotation(euclidean::multiply({qs.w, qs.u[0], qs.u[1], qs.u[2]}, q0));
}

}  // namespace

// The increment qs(v) * qs(v_hat)^* has vector part w_hat u - w u_hat - u x u_hat, whose
// derivative at v_hat, with u and w those of qs, is w_hat du - u_hat dw^T + [u_hat]x du; to first
// order that vector part is delta.
void rotation_tangent_jacobian(const double v_hat[3], double J[9]) {
  const sbaeuc_correction c = sbaeuc_correction_of(v_hat);
  const double *u = c.u;
  const double cross[9] = {0, -u[2], u[1], u[2], 0, -u[0], -u[1], u[0], 0};
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) {
      double s = c.w * c.du[r * 3 + k] - u[r] * c.dw[k];
      for (int l = 0; l < 3; ++l) s += cross[r * 3 + l] * c.du[l * 3 + k];
      J[r * 3 + k] = s;
    }
}

namespace {

// The largest parameter count of the cameras' models, each checked.
template <typename C>
int largest_param_count(const std::vector<C> &cameras) {
  int np = 0;
  for (std::size_t j = 0; j < cameras.size(); ++j)
    np = std::max(np, checked_param_count(j, cameras[j].model, cameras[j].params.size()));
  return np;
}

// The largest number of model parameters that a camera's vector carries: every one, or those
// `kept` gives it (CameraModel); every camera checked.
template <typename C>
int largest_carried(const std::vector<C> &cameras, const std::vector<std::vector<int>> &kept) {
  const int np = largest_param_count(cameras);
  if (!kept.empty() && kept.size() != cameras.size())
    throw std::invalid_argument("the parameters kept must be given per camera");
  return kept.empty() ? np : largest_kept(kept);
}

}  // namespace

namespace {

// refused's body, inlined where the model is a constant (eval_as).
inline __attribute__((always_inline)) bool refused_model(int model, const double *params, const double Xc[3]) {
  switch (model) {
    case kSimpleDivision: case kDivision: {
      const double k = params[kModels[model].params - 1];
      return Xc[2] * Xc[2] - 4 * k * (Xc[0] * Xc[0] + Xc[1] * Xc[1]) < 0;
    }
    case kEquirectangular: return false;
    default: return Xc[2] < DBL_EPSILON;
  }
}

}  // namespace

bool refused(int model, const double *params, const double Xc[3]) { return refused_model(model, params, Xc); }

SbaCameraModel::SbaCameraModel(int m, int cnp, int first, std::vector<double> points, std::vector<char> held)
    : m_(m), cnp_(cnp), first_(first), held_(std::move(held)), points0_(std::move(points)) {
  if (points0_.size() % kPointParams != 0) throw std::invalid_argument("point coordinates must come in threes");
  const std::size_t size = static_cast<std::size_t>(m) * static_cast<std::size_t>(cnp);
  if (!held_.empty() && held_.size() != size) throw std::invalid_argument("the held flags must be cnp per camera");
  cams0_.assign(size, 0.0);
  params0_.assign(static_cast<std::size_t>(m) * kMaxParams, 0.0);
  slot_.assign(static_cast<std::size_t>(m) * kMaxParams, -1);
  nparams_.assign(static_cast<std::size_t>(m), 0);
}

void SbaCameraModel::set_params(int j, const std::vector<double> &params, const std::vector<int> *kept) {
  const std::size_t at = static_cast<std::size_t>(j) * kMaxParams;
  const int np = static_cast<int>(params.size());
  std::copy(params.begin(), params.end(), params0_.begin() + static_cast<std::ptrdiff_t>(at));
  nparams_[static_cast<std::size_t>(j)] = static_cast<signed char>(np);
  const int nk = kept ? static_cast<int>(kept->size()) : np;
  for (int s = 0; s < nk; ++s) {
    const int k = kept ? (*kept)[static_cast<std::size_t>(s)] : s;
    if (k < 0 || k >= np || (s > 0 && kept && k <= (*kept)[static_cast<std::size_t>(s) - 1]))
      throw std::invalid_argument("camera " + std::to_string(j) + ": the parameters kept must be ascending indices " +
                                  "of its model's " + std::to_string(np));
    slot_[at + static_cast<std::size_t>(k)] = static_cast<signed char>(s);
    initial_camera(j)[first_ + s] = params[static_cast<std::size_t>(k)];
  }
}

void SbaCameraModel::expanded(int j, const double *a, double *out) const {
  const char *h = held(j);
  const double *a0 = initial_camera(j);
  const auto value = [&](int c) { return h && h[c] ? a0[c] : a[c]; };
  for (int c = 0; c < first_; ++c) out[c] = value(c);
  const std::size_t at = static_cast<std::size_t>(j) * kMaxParams;
  for (int k = 0; k < nparams_[static_cast<std::size_t>(j)]; ++k) {
    const int s = slot_[at + static_cast<std::size_t>(k)];
    out[first_ + k] = s < 0 ? params0_[at + static_cast<std::size_t>(k)] : value(first_ + s);
  }
}

int largest_kept(const std::vector<std::vector<int>> &kept) {
  std::size_t most = 0;
  for (const std::vector<int> &k : kept) most = std::max(most, k.size());
  return static_cast<int>(most);
}

CameraModel::CameraModel(const std::vector<Camera> &cameras, std::vector<double> points, std::vector<char> held,
                         const std::vector<std::vector<int>> &kept)
    : SbaCameraModel(static_cast<int>(cameras.size()),
                     camera_params(largest_carried(cameras, kept)), kPoseParams, std::move(points), std::move(held)) {
  const std::size_t m = cameras.size();
  cameras0_.reserve(m);
  R0_.resize(m * 9);
  for (std::size_t j = 0; j < m; ++j) {
    Camera c = cameras[j];
    c.q = unit_rotation(j, c.q, &R0_[j * 9]);
    double *a = initial_camera(static_cast<int>(j));  // v = 0: the input rotation
    for (int k = 0; k < 3; ++k) a[3 + k] = c.t[static_cast<std::size_t>(k)];
    set_params(static_cast<int>(j), c.params, kept.empty() ? nullptr : &kept[j]);
    cameras0_.push_back(std::move(c));
  }
}

Camera CameraModel::camera(int j, const double *given) const {
  Camera c = cameras0_[static_cast<std::size_t>(j)];
  double a[kPoseParams + kMaxParams];
  expanded(j, given, a);
  c.q = corrected(a, c.q);
  for (int k = 0; k < 3; ++k) c.t[static_cast<std::size_t>(k)] = a[3 + k];
  std::copy(a + kPoseParams, a + kPoseParams + c.params.size(), c.params.begin());
  return c;
}

RigCameraModel::RigCameraModel(const std::vector<RigImage> &images, std::vector<double> points,
                               std::vector<char> held, const std::vector<std::vector<int>> &kept)
    : SbaCameraModel(static_cast<int>(images.size()), rig_camera_params(largest_carried(images, kept)),
                     kRigPoseParams, std::move(points), std::move(held)) {
  const std::size_t m = images.size();
  images0_.reserve(m);
  R0_.resize(m * 18);
  for (std::size_t j = 0; j < m; ++j) {
    RigImage im = images[j];
    im.q_frame = unit_rotation(j, im.q_frame, &R0_[j * 18]);
    im.q_sensor = unit_rotation(j, im.q_sensor, &R0_[j * 18 + 9]);
    double *a = initial_camera(static_cast<int>(j));  // v_f = v_s = 0: the input rotations
    for (int k = 0; k < 3; ++k) {
      a[3 + k] = im.t_frame[static_cast<std::size_t>(k)];
      a[9 + k] = im.t_sensor[static_cast<std::size_t>(k)];
    }
    set_params(static_cast<int>(j), im.params, kept.empty() ? nullptr : &kept[j]);
    images0_.push_back(std::move(im));
  }
}

RigImage RigCameraModel::image(int j, const double *given) const {
  RigImage im = images0_[static_cast<std::size_t>(j)];
  double a[kRigPoseParams + kMaxParams];
  expanded(j, given, a);
  im.q_frame = corrected(a, im.q_frame);
  im.q_sensor = corrected(a + 6, im.q_sensor);
  for (int k = 0; k < 3; ++k) {
    im.t_frame[static_cast<std::size_t>(k)] = a[3 + k];
    im.t_sensor[static_cast<std::size_t>(k)] = a[9 + k];
  }
  std::copy(a + kRigPoseParams, a + kRigPoseParams + im.params.size(), im.params.begin());
  return im;
}

Camera RigCameraModel::camera(int j, const double *a) const {
  const RigImage im = image(j, a);
  Camera c;
  c.model = im.model;
  c.params = im.params;
  const auto pose = [](const euclidean::Quaternion &q, const std::array<double, 3> &t) {
    return RigidPose{{q.w, q.x, q.y, q.z}, t};
  };
  const RigidPose p = compose(pose(im.q_sensor, im.t_sensor), pose(im.q_frame, im.t_frame));
  c.q = euclidean::normalized_rotation({p.q[0], p.q[1], p.q[2], p.q[3]});
  c.t = p.t;
  return c;
}

namespace {

// C = A B for row-major 3x3 matrices.
void mat3_mul(const double *A, const double *B, double *C) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) C[r * 3 + c] = A[r * 3] * B[c] + A[r * 3 + 1] * B[3 + c] + A[r * 3 + 2] * B[6 + c];
}

// One rotation of the local parametrization: M = R(qs(v)) R0, and G, the rotation vector of
// the left increment that a change dv makes: R(qs(v + dv)) = exp([G dv]x) R(qs(v)) to first
// order (twice rotation_tangent_jacobian).
struct LocalRotation {
  double M[9];
  double G[9];
};

// G only where a Jacobian will be formed (tangent): a projection alone does not read it.
LocalRotation local_rotation(const double *v, const double *R0, bool tangent) {
  LocalRotation r{};
  const sbaeuc_correction qs = sbaeuc_correction_of(v);
  double Rs[9];
  sbaeuc_rotation_matrix(qs.w, qs.u[0], qs.u[1], qs.u[2], Rs);
  mat3_mul(Rs, R0, r.M);
  if (!tangent) return r;
  rotation_tangent_jacobian(v, r.G);
  for (double &g : r.G) g *= 2;
  return r;
}

// A = H J for H 2x3 and J 3x3, into columns col..col+2 of the 2 x cnp A.
inline __attribute__((always_inline)) void columns(const double *H, const double *J, int cnp, int col, double *A) {
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c)
      A[r * cnp + col + c] = H[r * 3] * J[c] + H[r * 3 + 1] * J[3 + c] + H[r * 3 + 2] * J[6 + c];
}

// The camera model's pixels and derivatives at Xc: x, Jx = dx/dXc and the parameters' columns
// of A (parameter k at col + slots[k] where that is not -1, then zero padding to cnp), the held
// columns zeroed afterwards by zero_held.
inline __attribute__((always_inline)) void project_at(int model, int np, const double *params, const double Xc[3],
                                                      int cnp, int col, const signed char *slots, double *x,
                                                      double *A, double Jx[6]) {
  double Jp[2 * kMaxParams];
  project_model(model, params, Xc, x, A ? Jp : nullptr, Jx);
  if (!A) return;
  for (int r = 0; r < 2; ++r) {
    double *Ar = A + r * cnp;
    int end = col;  // the slots are 0, 1, ... in the order of k
    for (int k = 0; k < np; ++k) {
      if (slots[k] < 0) continue;
      end = col + slots[k];
      Ar[end++] = Jp[r * np + k];
    }
    for (int c = end; c < cnp; ++c) Ar[c] = 0.0;
  }
}

// A camera's held columns (of its cnp flags), listed once per camera so that the Jacobian of
// each projection zeroes them without testing every column's flag.
struct HeldColumns {
  int n = 0;
  unsigned char col[kRigPoseParams + kMaxParams];
};

HeldColumns held_columns(const char *held, int cnp) {
  HeldColumns h;
  for (int k = 0; held && k < cnp; ++k)
    if (held[k]) h.col[h.n++] = static_cast<unsigned char>(k);
  return h;
}

void zero_held(const HeldColumns &held, int cnp, double *A) {
  for (int i = 0; i < held.n; ++i) A[held.col[i]] = A[cnp + held.col[i]] = 0.0;
}

// What a projection needs of camera j that does not depend on the point.
struct Frame {
  int model, np;
  double a[kPoseParams + kMaxParams];  // the pose and the model's parameters (expanded)
  const signed char *slots;            // the model's parameters' columns after the pose
  HeldColumns held;
  LocalRotation rot;
  // Offsets into a rather than pointers: a Frame is copied.
  const double *params() const { return a + kPoseParams; }
  const double *t() const { return a + 3; }
};

Frame frame_of(const CameraModel &model, int j, const double *a, bool tangent) {
  Frame f;
  f.model = model.input_camera(j).model;
  f.np = param_count(f.model);
  model.expanded(j, a, f.a);
  f.slots = model.slots(j);
  f.held = held_columns(model.held(j), model.cnp());
  f.rot = local_rotation(f.a, model.initial_rotation(j), tangent);
  return f;
}

// What a projection COLMAP refuses gives with measurements (SbaCameraModel::set_measurements):
// hx its measurement obs, a zero Jacobian. False, as eval returns for it.
bool cost_nothing(const double *obs, int cnp, double *x, double *A, double *B) {
  if (x) {
    x[0] = obs[0];
    x[1] = obs[1];
  }
  if (A) std::fill(A, A + 2 * cnp, 0.0);
  if (B) std::fill(B, B + 6, 0.0);
  return false;
}

// The projection of b and its Jacobian (any of x, A, B null), false where COLMAP refuses it;
// there, with obs (the projection's measurement), as cost_nothing says. kModel is f.model as a
// constant, or -1 (any model, read from f): see eval below.
template <int kModel>
bool eval_as(const Frame &f, int cnp, const double *b, const double *obs, double *x, double *A, double *B) {
  const int model = kModel < 0 ? f.model : kModel, np = kModel < 0 ? f.np : kModels[model].params;
  double MX[3], Xc[3];
  sbaeuc_mat3_vec(f.rot.M, b, MX);
  for (int r = 0; r < 3; ++r) Xc[r] = MX[r] + f.t()[r];
  const bool shown = !refused_model(model, f.params(), Xc);
  if (!shown && obs) return cost_nothing(obs, cnp, x, A, B);
  double Jx[6];
  project_at(model, np, f.params(), Xc, cnp, kPoseParams, f.slots, x, A, (A || B) ? Jx : nullptr);
  if (B) columns(Jx, f.rot.M, 3, 0, B);
  if (!A) return shown;
  rotation_columns(Jx, MX, f.rot.G, cnp, 0, A);
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) A[r * cnp + 3 + c] = Jx[r * 3 + c];
  zero_held(f.held, cnp, A);
  return shown;
}

// What a projection needs of rig image j that does not depend on the point.
struct RigFrame {
  int model, np;
  double a[kRigPoseParams + kMaxParams];  // the poses and the model's parameters (expanded)
  const signed char *slots;               // the model's parameters' columns after the poses
  HeldColumns held;
  LocalRotation frame, sensor;            // R_f and R_s
  double M[9];                            // R_s R_f: d X_c / d X
  const double *params() const { return a + kRigPoseParams; }
  const double *t_frame() const { return a + 3; }
  const double *t_sensor() const { return a + 9; }
};

RigFrame frame_of(const RigCameraModel &model, int j, const double *a, bool tangent) {
  RigFrame f;
  f.model = model.input_image(j).model;
  f.np = param_count(f.model);
  model.expanded(j, a, f.a);
  f.slots = model.slots(j);
  f.held = held_columns(model.held(j), model.cnp());
  f.frame = local_rotation(f.a, model.initial_frame_rotation(j), tangent);
  f.sensor = local_rotation(f.a + 6, model.initial_sensor_rotation(j), tangent);
  mat3_mul(f.sensor.M, f.frame.M, f.M);
  return f;
}

// X_r = R_f X + t_f in the rig, X_c = R_s X_r + t_s: dX_c/dv_f = R_s dR_f X/dv_f, dX_c/dt_f =
// R_s, dX_c/dv_s = dR_s X_r/dv_s, dX_c/dt_s = I, dX_c/dX = R_s R_f.
template <int kModel>
bool eval_as(const RigFrame &f, int cnp, const double *b, const double *obs, double *x, double *A, double *B) {
  const int model = kModel < 0 ? f.model : kModel, np = kModel < 0 ? f.np : kModels[model].params;
  double MfX[3], Xr[3], MsXr[3], Xc[3];
  sbaeuc_mat3_vec(f.frame.M, b, MfX);
  for (int r = 0; r < 3; ++r) Xr[r] = MfX[r] + f.t_frame()[r];
  sbaeuc_mat3_vec(f.sensor.M, Xr, MsXr);
  for (int r = 0; r < 3; ++r) Xc[r] = MsXr[r] + f.t_sensor()[r];
  const bool shown = !refused_model(model, f.params(), Xc);
  if (!shown && obs) return cost_nothing(obs, cnp, x, A, B);
  double Jx[6];
  project_at(model, np, f.params(), Xc, cnp, kRigPoseParams, f.slots, x, A, (A || B) ? Jx : nullptr);
  if (B) columns(Jx, f.M, 3, 0, B);
  if (!A) return shown;
  double H[6];  // H = dx/dX_r = Jx R_s
  columns(Jx, f.sensor.M, 3, 0, H);
  rotation_columns(H, MfX, f.frame.G, cnp, 0, A);
  rotation_columns(Jx, MsXr, f.sensor.G, cnp, 6, A);
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) {
      A[r * cnp + 3 + c] = H[r * 3 + c];
      A[r * cnp + 9 + c] = Jx[r * 3 + c];
    }
  zero_held(f.held, cnp, A);
  return shown;
}

// eval_as for f's model: compiled for each of the models COLMAP's users project most (the
// pinholes and the radial and OpenCV models, COLMAP's defaults), with the model a constant;
// through the run-time model for the others. Every instance does the same arithmetic in the
// same order, so the bits do not depend on which one runs (the callbacks' tests compare them
// with project_jacobian, which runs the code for any model).
template <class FrameT>
bool eval(const FrameT &f, int cnp, const double *b, const double *obs, double *x, double *A, double *B) {
  switch (f.model) {
    case kSimplePinhole: return eval_as<kSimplePinhole>(f, cnp, b, obs, x, A, B);
    case kPinhole: return eval_as<kPinhole>(f, cnp, b, obs, x, A, B);
    case kSimpleRadial: return eval_as<kSimpleRadial>(f, cnp, b, obs, x, A, B);
    case kRadial: return eval_as<kRadial>(f, cnp, b, obs, x, A, B);
    case kOpenCV: return eval_as<kOpenCV>(f, cnp, b, obs, x, A, B);
    default: return eval_as<-1>(f, cnp, b, obs, x, A, B);
  }
}

inline std::size_t off(int index, int stride) {
  return static_cast<std::size_t>(index) * static_cast<std::size_t>(stride);
}

// Calls f(i, frame of camera j, ordinal) for every projection of the rows of idx, the frames
// of the cameras those rows see set up once per call rather than once per projection. A call
// may be given a part of the rows (parallel_callbacks): it prepares only what those rows use.
// tangent: the frames are for Jacobians.
template <typename Model, typename F>
void for_each_projection(const Model &model, const double *p, const sba_crsm &idx, bool tangent, F &&f) {
  const int m = model.ncameras(), cnp = model.cnp();
  using Prepared = decltype(frame_of(model, 0, p, tangent));
  std::vector<Prepared> frames(static_cast<std::size_t>(m));
  std::vector<char> ready(static_cast<std::size_t>(m), 0);
  for (int i = 0; i < idx.nr; ++i)
    for (int e = idx.rowptr[i]; e < idx.rowptr[i + 1]; ++e) {
      const int j = idx.colidx[e];
      if (!ready[static_cast<std::size_t>(j)]) {
        frames[static_cast<std::size_t>(j)] = frame_of(model, j, p + off(j, cnp), tangent);
        ready[static_cast<std::size_t>(j)] = 1;
      }
      f(i, frames[static_cast<std::size_t>(j)], idx.val[e]);
    }
}

// The expert callbacks of either model (adata a Model): hx, or A_ij then B_ij, at each
// projection's ordinal.
template <typename Model>
void func_of(const double *p, const sba_crsm &idx, double *hx, void *adata) {
  const Model &model = *static_cast<const Model *>(adata);
  const int cnp = model.cnp();
  const double *pb = p + off(model.ncameras(), cnp);
  const double *x = model.measurements();
  for_each_projection(model, p, idx, false, [&](int i, const auto &f, int k) {
    eval(f, cnp, pb + off(i, kPointParams), x ? x + off(k, kMeasurementParams) : nullptr,
         hx + off(k, kMeasurementParams), nullptr, nullptr);
  });
}

template <typename Model>
void fjac_of(const double *p, const sba_crsm &idx, double *jac, void *adata) {
  const Model &model = *static_cast<const Model *>(adata);
  const int cnp = model.cnp();
  const double *pb = p + off(model.ncameras(), cnp);
  const int block = kMeasurementParams * (cnp + kPointParams);
  const double *x = model.measurements();
  for_each_projection(model, p, idx, true, [&](int i, const auto &f, int k) {
    double *A = jac + off(k, block);
    eval(f, cnp, pb + off(i, kPointParams), x ? x + off(k, kMeasurementParams) : nullptr, nullptr, A,
         A + kMeasurementParams * cnp);
  });
}

}  // namespace

template <class Model>
struct CachedProjection<Model>::Impl {
  using Prepared = decltype(frame_of(std::declval<const Model &>(), 0, nullptr, false));
  const Model &model;
  std::vector<Prepared> frames;
  std::vector<double> params;  // each camera's, as its frame was made
  std::vector<char> ready;
};

template <class Model>
CachedProjection<Model>::CachedProjection(const Model &model)
    : impl_(new Impl{model, std::vector<typename Impl::Prepared>(off(model.ncameras(), 1)),
                     std::vector<double>(off(model.ncameras(), model.cnp())),
                     std::vector<char>(off(model.ncameras(), 1), 0)}) {}

template <class Model>
CachedProjection<Model>::~CachedProjection() = default;

template <class Model>
bool CachedProjection<Model>::project(int j, const double *a, const double *b, double x[2]) {
  Impl &c = *impl_;
  const int cnp = c.model.cnp();
  double *kept = c.params.data() + off(j, cnp);
  const std::size_t bytes = off(cnp, sizeof(double));
  if (!c.ready[off(j, 1)] || std::memcmp(a, kept, bytes) != 0) {
    c.frames[off(j, 1)] = frame_of(c.model, j, a, false);
    std::memcpy(kept, a, bytes);
    c.ready[off(j, 1)] = 1;
  }
  return eval(c.frames[off(j, 1)], cnp, b, nullptr, x, nullptr, nullptr);
}

template class CachedProjection<CameraModel>;
template class CachedProjection<RigCameraModel>;

// One projection at a time, through the code for any model: the reference that the callbacks'
// code for each model is tested against (their bits are the same).
bool CameraModel::project_jacobian(int j, const double *a, const double *b, double *x, double *A, double *B) const {
  return eval_as<-1>(frame_of(*this, j, a, A != nullptr), cnp(), b, nullptr, x, A, B);
}

bool RigCameraModel::project_jacobian(int j, const double *a, const double *b, double *x, double *A,
                                      double *B) const {
  return eval_as<-1>(frame_of(*this, j, a, A != nullptr), cnp(), b, nullptr, x, A, B);
}

void motstr_func(double *p, sba_crsm *idx, int *, int *, double *hx, void *adata) {
  func_of<CameraModel>(p, *idx, hx, adata);
}

void motstr_fjac(double *p, sba_crsm *idx, int *, int *, double *jac, void *adata) {
  fjac_of<CameraModel>(p, *idx, jac, adata);
}

void rig_motstr_func(double *p, sba_crsm *idx, int *, int *, double *hx, void *adata) {
  func_of<RigCameraModel>(p, *idx, hx, adata);
}

void rig_motstr_fjac(double *p, sba_crsm *idx, int *, int *, double *jac, void *adata) {
  fjac_of<RigCameraModel>(p, *idx, jac, adata);
}

}  // namespace sbacameras::colmap_camera
