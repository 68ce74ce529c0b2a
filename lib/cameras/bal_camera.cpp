// SPDX-License-Identifier: BSD-3-Clause
#include "cameras/bal_camera.h"

#include <cmath>
#include <cstddef>
#include <memory>
#include <new>

#include "cameras/camera_pose.h"
#include "sba.h"

namespace sbacameras::bal {
namespace {

// Below this |w|^2 the Rodrigues coefficients come from their series.
constexpr double kSeriesLimit = 1.0 / 16.0;
constexpr int kSeriesTerms = 8;

// alpha(s) = sin(t)/t and beta(s) = (1 - cos t)/t^2 with t = sqrt(s).
struct Coefficients {
  double alpha, beta;
};

// alpha = sum_k (-1)^k s^k / (2k+1)!,  beta = sum_k (-1)^k s^k / (2k+2)!.
struct SeriesTable {
  double a[kSeriesTerms], b[kSeriesTerms];
  constexpr SeriesTable() : a(), b() {
    double fact = 1;  // (2k+1)! for the current k, starting at 1! = 1
    for (int k = 0; k < kSeriesTerms; ++k) {
      if (k > 0) fact *= (2 * k) * (2 * k + 1);
      const double sign = (k % 2 == 0) ? 1.0 : -1.0;
      a[k] = sign / fact;
      b[k] = sign / (fact * (2 * k + 2));
    }
  }
};
constexpr SeriesTable kSeries;

Coefficients coefficients(double s) {
  Coefficients c{};
  if (s < kSeriesLimit) {
    // Horner from the last term.
    double a = 0, b = 0;
    for (int k = kSeriesTerms - 1; k >= 0; --k) {
      a = a * s + kSeries.a[k];
      b = b * s + kSeries.b[k];
    }
    c = {a, b};
    return c;
  }
  const double t = std::sqrt(s);
  const double sh = std::sin(0.5 * t);
  c.alpha = std::sin(t) / t;
  c.beta = 2.0 * sh * sh / s;  // (1 - cos t) without its cancellation
  return c;
}

template <class T>
inline void cross(const T a[3], const T b[3], T c[3]) {
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}

// R = (1 - beta s) I + alpha [w]x + beta w w^T, with s = |w|^2 and c = coefficients(s).
void fill_rotation(const double w[3], double s, const Coefficients &c, double R[9]) {
  const double diag = 1.0 - c.beta * s;
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) R[r * 3 + k] = c.beta * w[r] * w[k] + (r == k ? diag : 0.0);
  R[1] -= c.alpha * w[2];
  R[2] += c.alpha * w[1];
  R[3] += c.alpha * w[2];
  R[5] -= c.alpha * w[0];
  R[6] -= c.alpha * w[1];
  R[7] += c.alpha * w[0];
}

}  // namespace

void rotation_matrix(const double w[3], double R[9]) {
  const double s = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
  fill_rotation(w, s, coefficients(s), R);
}

namespace {

// gamma(s) = (1 - alpha)/s = (t - sin t)/t^3, from its series sum_k (-1)^k s^k / (2k+3)!
// below kSeriesLimit, where 1 - alpha cancels.
double gamma_of(double s, double alpha) {
  if (s >= kSeriesLimit) return (1.0 - alpha) / s;
  double g = 0;
  for (int k = kSeriesTerms - 2; k >= 0; --k) g = g * s - kSeries.a[k + 1];
  return g;
}

// What a projection needs of its camera's rotation and does not depend on the point: the
// callbacks make it once per camera instead of once per observation (three sines and a
// cosine each time); the values are the same either way. G is the left Jacobian of the
// rotation, alpha I + beta [w]x + gamma w w^T: d(R(w) X)/dw = -[R(w) X]x G for every X.
struct RotationTerms {
  double s;
  Coefficients c;
  double R[9];
  double G[9];
};

void rotation_terms(const double w[3], RotationTerms *rt) {
  rt->s = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
  rt->c = coefficients(rt->s);
  fill_rotation(w, rt->s, rt->c, rt->R);
  const double alpha = rt->c.alpha, beta = rt->c.beta, gamma = gamma_of(rt->s, alpha);
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) rt->G[r * 3 + k] = gamma * w[r] * w[k] + (r == k ? alpha : 0.0);
  rt->G[1] -= beta * w[2];
  rt->G[2] += beta * w[1];
  rt->G[3] += beta * w[2];
  rt->G[5] -= beta * w[0];
  rt->G[6] -= beta * w[1];
  rt->G[7] += beta * w[0];
}

// The projection of b by a and its derivatives (any of x, A, B null), from a's rotation
// terms. T is double, or a vector of doubles that carries projections side by side, each in
// its lane with the operations, and so the bits, of the double. Inlined into its callers:
// called, the vector version hands its results back through memory.
template <class T>
inline __attribute__((always_inline)) void project_t(const T *a, T alpha, T beta, const T *R, const T *G,
                                                     const T *b, T *x, T *A, T *B) {
  const T *w = a, *t = a + 3;
  const T f = a[6], k1 = a[7], k2 = a[8];

  T wX[3], wwX[3];
  cross(w, b, wX);
  cross(w, wX, wwX);
  T Q[3];
  for (int r = 0; r < 3; ++r) Q[r] = b[r] + alpha * wX[r] + beta * wwX[r] + t[r];

  const T iz = 1.0 / Q[2];
  const T px = -Q[0] * iz, py = -Q[1] * iz;
  const T r2 = px * px + py * py;
  const T d = 1.0 + r2 * (k1 + k2 * r2);
  if (x) {
    x[0] = f * d * px;
    x[1] = f * d * py;
  }
  if (!A && !B) return;

  // d x / d p = f (d I + 2 (k1 + 2 k2 r2) p p^T), symmetric.
  const T g = 2.0 * (k1 + 2.0 * k2 * r2);
  const T Jxx = f * (d + g * px * px), Jxy = f * g * px * py, Jyy = f * (d + g * py * py);
  // d p / d Q = -(1/Q3) [1 0 px; 0 1 py], so H = d x / d Q is:
  const T H[6] = {-iz * Jxx, -iz * Jxy, -iz * (Jxx * px + Jxy * py),
                  -iz * Jxy, -iz * Jyy, -iz * (Jxy * px + Jyy * py)};

  if (B) {
    // d Q / d X = R(w).
    for (int r = 0; r < 2; ++r)
      for (int k = 0; k < 3; ++k)
        B[r * 3 + k] = H[r * 3] * R[k] + H[r * 3 + 1] * R[3 + k] + H[r * 3 + 2] * R[6 + k];
  }
  if (!A) return;

  // d Q / d w through the left Jacobian G, at R X = Q - t.
  const T RX[3] = {Q[0] - t[0], Q[1] - t[1], Q[2] - t[2]};
  rotation_columns(H, RX, G, kCameraParams, 0, A);
  T *A0 = A, *A1 = A + kCameraParams;
  for (int k = 0; k < 3; ++k) {
    A0[3 + k] = H[k];  // d Q / d t = I
    A1[3 + k] = H[3 + k];
  }
  A0[6] = d * px;
  A1[6] = d * py;
  A0[7] = f * r2 * px;
  A1[7] = f * r2 * py;
  A0[8] = f * r2 * r2 * px;
  A1[8] = f * r2 * r2 * py;
}

void project_with(const double a[kCameraParams], const RotationTerms &rt, const double b[kPointParams],
                  double *x, double *A, double *B) {
  project_t<double>(a, rt.c.alpha, rt.c.beta, rt.R, rt.G, b, x, A, B);
}

// Two doubles side by side, in the vector registers of the target (SSE2 on x86-64, NEON on
// AArch64) or as a pair of scalars where it has none.
typedef double Lanes __attribute__((vector_size(2 * sizeof(double))));

// One projection's inputs, the ones project_t takes per projection.
struct Projection {
  const double *a;
  const RotationTerms *rt;
  const double *b;
};

// Two projections at once, each in its lane: the arithmetic of project_with once for both.
// Their cameras' and points' parameters, lane by lane.
struct TwoInputs {
  Lanes a[kCameraParams], b[kPointParams], alpha, beta;
  TwoInputs(const Projection &p, const Projection &q)
      : alpha{p.rt->c.alpha, q.rt->c.alpha}, beta{p.rt->c.beta, q.rt->c.beta} {
    for (int k = 0; k < kCameraParams; ++k) a[k] = Lanes{p.a[k], q.a[k]};
    for (int k = 0; k < kPointParams; ++k) b[k] = Lanes{p.b[k], q.b[k]};
  }
};

// project_with's x of p into x0 and of q into x1.
void project_two(const Projection &p, const Projection &q, double *x0, double *x1) {
  const TwoInputs in(p, q);
  Lanes x[kMeasurementParams];
  project_t<Lanes>(in.a, in.alpha, in.beta, nullptr, nullptr, in.b, x, nullptr, nullptr);
  for (int r = 0; r < kMeasurementParams; ++r) x0[r] = x[r][0], x1[r] = x[r][1];
}

// project_with's A and B of p into A0 and B0, of q into A1 and B1.
void project_two(const Projection &p, const Projection &q, double *A0, double *B0, double *A1, double *B1) {
  const TwoInputs in(p, q);
  Lanes R[9], G[9];
  for (int k = 0; k < 9; ++k) R[k] = Lanes{p.rt->R[k], q.rt->R[k]}, G[k] = Lanes{p.rt->G[k], q.rt->G[k]};
  Lanes A[kMeasurementParams * kCameraParams], B[kMeasurementParams * kPointParams];
  project_t<Lanes>(in.a, in.alpha, in.beta, R, G, in.b, nullptr, A, B);
  for (int k = 0; k < kMeasurementParams * kCameraParams; ++k) A0[k] = A[k][0];
  for (int k = 0; k < kMeasurementParams * kPointParams; ++k) B0[k] = B[k][0];
  for (int k = 0; k < kMeasurementParams * kCameraParams; ++k) A1[k] = A[k][1];
  for (int k = 0; k < kMeasurementParams * kPointParams; ++k) B1[k] = B[k][1];
}

}  // namespace

void project_jacobian(const double a[kCameraParams], const double b[kPointParams], double *x,
                      double *A, double *B) {
  RotationTerms rt;
  rotation_terms(a, &rt);
  project_with(a, rt, b, x, A, B);
}

void project(const double a[kCameraParams], const double b[kPointParams], double x[2]) {
  project_jacobian(a, b, x, nullptr, nullptr);
}

// ---- callbacks ----

namespace {

inline std::size_t off(int index, int stride) {
  return static_cast<std::size_t>(index) * static_cast<std::size_t>(stride);
}

// Calls two(P, its measurement ordinal, Q, its ordinal) for the projections in idx two at a
// time (idx may be a part of the rows when callbacks run concurrently), and one(P, ordinal)
// for the last where their number is odd. The per-camera terms live in a buffer of this call;
// without memory for it, each projection makes its own and goes to one alone, with the same
// result.
template <class Two, class One>
void for_each_projection(const double *p, const sba_crsm *idx, const void *adata, Two two, One one) {
  const int m = static_cast<const CallbackData *>(adata)->ncameras;
  const double *pb = p + off(m, kCameraParams);
  std::unique_ptr<RotationTerms[]> terms(new (std::nothrow) RotationTerms[size_t(m > 0 ? m : 0)]);
  if (terms)
    for (int j = 0; j < m; ++j) rotation_terms(p + off(j, kCameraParams), &terms[size_t(j)]);
  RotationTerms own;
  Projection held{};
  int held_k = -1;
  for (int i = 0; i < idx->nr; ++i)
    for (int e = idx->rowptr[i]; e < idx->rowptr[i + 1]; ++e) {
      const int j = idx->colidx[e];
      const double *a = p + off(j, kCameraParams);
      const Projection now{a, terms ? &terms[size_t(j)] : (rotation_terms(a, &own), &own), pb + off(i, kPointParams)};
      if (!terms) {
        one(now, idx->val[e]);
      } else if (held_k < 0) {
        held = now;
        held_k = idx->val[e];
      } else {
        two(held, held_k, now, idx->val[e]);
        held_k = -1;
      }
    }
  if (held_k >= 0) one(held, held_k);
}

}  // namespace

void motstr_func(double *p, sba_crsm *idx, int *, int *, double *hx, void *adata) {
  const auto at = [hx](int k) { return hx + off(k, kMeasurementParams); };
  for_each_projection(
      p, idx, adata,
      [&](const Projection &P, int kp, const Projection &Q, int kq) {
        project_two(P, Q, at(kp), at(kq));
      },
      [&](const Projection &P, int k) { project_with(P.a, *P.rt, P.b, at(k), nullptr, nullptr); });
}

void motstr_fjac(double *p, sba_crsm *idx, int *, int *, double *jac, void *adata) {
  constexpr int block = kMeasurementParams * (kCameraParams + kPointParams), nA = kMeasurementParams * kCameraParams;
  const auto at = [jac](int k) { return jac + off(k, block); };
  for_each_projection(
      p, idx, adata,
      [&](const Projection &P, int kp, const Projection &Q, int kq) {
        project_two(P, Q, at(kp), at(kp) + nA, at(kq), at(kq) + nA);
      },
      [&](const Projection &P, int k) { project_with(P.a, *P.rt, P.b, nullptr, at(k), at(k) + nA); });
}

void motstr_proj(int, int, double *aj, double *bi, double *xij, void *) { project(aj, bi, xij); }
void motstr_projac(int, int, double *aj, double *bi, double *Aij, double *Bij, void *) {
  project_jacobian(aj, bi, nullptr, Aij, Bij);
}

}  // namespace sbacameras::bal
