// SPDX-License-Identifier: BSD-3-Clause
// The priors of a solve: their check (one message per fault, naming the prior), their
// residuals and their blocks of the normal equations, and the check of the callback priors'
// Jacobians.
#include "priors.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>

#include "model.h"
#include "small_dense.h"

namespace sba {
namespace {

// Residuals of more entries are not what a prior is: the blocks are handled as small dense.
constexpr int kMaxPriorDim = 64;

// A value as the messages give it (%g).
std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

std::string entry(int r, int c) { return "(" + std::to_string(r) + ", " + std::to_string(c) + ")"; }

// What is wrong with a k x k sqrt_info (finite): empty if nothing.
std::string check_sqrt_info(const double *a, int k) {
  for (int r = 0; r < k; ++r) {
    if (!(a[r * k + r] > 0.0))
      return "weight.sqrt_info's diagonal must be positive (entry " + entry(r, r) + " is " + num(a[r * k + r]) + ")";
    for (int c = 0; c < r; ++c)
      if (a[r * k + c] != 0.0)
        return "weight.sqrt_info must be upper triangular (entry " + entry(r, c) + " is " + num(a[r * k + c]) + ")";
  }
  return {};
}

// What is wrong with a k x k covariance (finite): empty if nothing.
std::string check_covariance(const double *a, int k) {
  for (int r = 0; r < k; ++r)
    for (int c = r + 1; c < k; ++c)
      if (a[r * k + c] != a[c * k + r]) return "weight.covariance is not symmetric (entries " + entry(r, c) + ")";
  std::vector<double> t(a, a + k * k), L(t.size()), tmp(t.size());
  if (!small::cholinv_upper(t.data(), L.data(), tmp.data(), k)) return "weight.covariance is not positive definite";
  return {};
}

// What is wrong with a weight of k entries; empty: nothing.
std::string check_weight(const sba_prior_weight &w, int k) {
  const int given = (w.sigma != nullptr) + (w.covariance != nullptr) + (w.sqrt_info != nullptr);
  if (given > 1) return "give at most one of weight.sigma, weight.covariance and weight.sqrt_info";
  for (int c = 0; w.sigma && c < k; ++c)
    if (!(std::isfinite(w.sigma[c]) && w.sigma[c] > 0.0))
      return "weight.sigma[" + std::to_string(c) + "] (a standard deviation) must be finite and positive (got " +
             num(w.sigma[c]) + ")";
  const double *a = w.covariance ? w.covariance : w.sqrt_info;
  const char *name = w.covariance ? "weight.covariance" : "weight.sqrt_info";
  for (int q = 0; a && q < k * k; ++q)
    if (!std::isfinite(a[q])) return std::string(name) + "[" + std::to_string(q) + "] is not finite";
  if (w.sqrt_info) return check_sqrt_info(a, k);
  if (w.covariance) return check_covariance(a, k);
  return {};
}

// The upper-triangular L of a checked weight.
std::vector<double> sqrt_information(const sba_prior_weight &w, int k) {
  std::vector<double> L(size_t(k) * size_t(k), 0.0);
  if (w.sqrt_info) {
    L.assign(w.sqrt_info, w.sqrt_info + k * k);
  } else if (w.covariance) {
    std::vector<double> a(w.covariance, w.covariance + k * k), tmp(L.size());
    small::cholinv_upper(a.data(), L.data(), tmp.data(), k);
  } else {
    for (int c = 0; c < k; ++c) L[size_t(c) * k + c] = w.sigma ? 1.0 / w.sigma[c] : 1.0;
  }
  return L;
}

// A prior's loss, named as sba_ext_options.loss; false (with why) when it cannot be used.
bool prior_loss(const char *name, double scale, Loss *out, std::string *why) {
  if (!name) return true;
  LossKind kind;
  if (!loss_from_name(name, &kind)) {
    *why = std::string("unknown loss \"") + name + "\" (known: " + loss_names() + ")";
    return false;
  }
  if (scale == 0.0) scale = 1.0;
  if (kind != LossKind::None && !(scale >= kMinLossScale && scale <= kMaxLossScale)) {
    char buf[120];
    std::snprintf(buf, sizeof buf, "loss_scale must be positive and within [%.3g, %.3g] (got %g)", kMinLossScale,
                  kMaxLossScale, scale);
    *why = buf;
    return false;
  }
  *out = Loss(kind, scale);
  return true;
}

// The weight, the loss and the mean (k values, null for a callback prior) of one prior.
template <class Prior>
std::string check_common(const Prior &pr, int k, const double *mean) {
  for (int c = 0; mean && c < k; ++c)
    if (!std::isfinite(mean[c])) return "mean[" + std::to_string(c) + "] is not finite";
  std::string why = check_weight(pr.weight, k);
  Loss loss;
  if (why.empty()) prior_loss(pr.loss, pr.loss_scale, &loss, &why);
  return why;
}

bool held_flag(const CameraParamOptions &cams, const Layout &lay, int j, int c) {
  return cams.fixed && cams.fixed[cams.fixed_per_camera ? size_t(j) * size_t(lay.cnp) + size_t(c) : size_t(c)] != 0;
}

// A camera that a prior may constrain: one of the problem's, not below mcon.
std::string check_camera(const Layout &lay, int j) {
  if (lay.cnp == 0) return "the driver has no cameras (structure only)";
  if (j < 0 || j >= lay.m) return "there is no such camera (m = " + std::to_string(lay.m) + ")";
  if (j < lay.mcon) return "the camera is fixed (below mcon = " + std::to_string(lay.mcon) + ")";
  return {};
}

std::string check_callback(const sba_camera_prior &pr, const Layout &lay, const CameraParamOptions &cams) {
  std::string why = check_camera(lay, pr.camera);
  if (!why.empty()) return why;
  if (pr.dim < 1 || pr.dim > kMaxPriorDim)
    return "dim must be in 1.." + std::to_string(kMaxPriorDim) + " (got " + std::to_string(pr.dim) + ")";
  if (!pr.func) return "func is NULL";
  int free = 0;
  for (int c = 0; c < lay.cnp; ++c) free += !held_flag(cams, lay, pr.camera, c);
  if (free == 0) return "every parameter of the camera is held (cam_fixed): the prior would change nothing";
  return check_common(pr, pr.dim, nullptr);
}

std::string check_linear(const sba_camera_linear_prior &pr, const Layout &lay, const CameraParamOptions &cams) {
  std::string why = check_camera(lay, pr.camera);
  if (!why.empty()) return why;
  if (pr.k < 1 || pr.k > lay.cnp)
    return "k must be in 1..cnp = 1.." + std::to_string(lay.cnp) + " (got " + std::to_string(pr.k) + ")";
  if (!pr.params || !pr.mean) return "params and mean must not be NULL";
  for (int q = 0; q < pr.k; ++q) {
    const int c = pr.params[q];
    const std::string at = "params[" + std::to_string(q) + "] = " + std::to_string(c);
    if (c < 0 || c >= lay.cnp) return at + " is not a camera parameter (cnp = " + std::to_string(lay.cnp) + ")";
    if (std::find(pr.params, pr.params + q, c) != pr.params + q) return at + " is named twice";
    if (held_flag(cams, lay, pr.camera, c))
      return at + " is held (cam_fixed): a prior on a held parameter would change nothing";
  }
  return check_common(pr, pr.k, pr.mean);
}

std::string check_point(const sba_point_prior &pr, const Layout &lay) {
  if (lay.pnp == 0) return "the driver has no points (motion only)";
  if (pr.point < 0 || pr.point >= lay.n) return "there is no such point (n = " + std::to_string(lay.n) + ")";
  if (pr.point < lay.ncon) return "the point is fixed (below ncon = " + std::to_string(lay.ncon) + ")";
  if (!pr.mean) return "mean is NULL";
  return check_common(pr, lay.pnp, pr.mean);
}

// The count and array of one kind of prior.
std::string check_array(const char *count, const char *array, int n, const void *p) {
  if (n < 0) return std::string(count) + " must be >= 0 (got " + std::to_string(n) + ")";
  if (n > 0 && !p) return std::string(array) + " is NULL but " + count + " is " + std::to_string(n);
  return {};
}

}  // namespace

i64 PriorOptions::rows(const Layout &lay) const {
  i64 r = i64(std::max(npoint, 0)) * lay.pnp;
  for (int q = 0; q < ncamera; ++q) r += camera[q].dim;
  for (int q = 0; q < nlinear; ++q) r += linear[q].k;
  return r;
}

std::string check_priors(const PriorOptions &o, const Layout &lay, const CameraParamOptions &cams) {
  std::string why = check_array("ncamera_priors", "camera_priors", o.ncamera, o.camera);
  if (why.empty()) why = check_array("ncamera_linear_priors", "camera_linear_priors", o.nlinear, o.linear);
  if (why.empty()) why = check_array("npoint_priors", "point_priors", o.npoint, o.point);
  if (!why.empty()) return why;
  const auto named = [](const char *what, int q, const char *of, int target, const std::string &w) {
    return std::string(what) + " " + std::to_string(q) + " (" + of + " " + std::to_string(target) + "): " + w;
  };
  for (int q = 0; q < o.ncamera; ++q)
    if (!(why = check_callback(o.camera[q], lay, cams)).empty())
      return named("camera prior", q, "camera", o.camera[q].camera, why);
  for (int q = 0; q < o.nlinear; ++q)
    if (!(why = check_linear(o.linear[q], lay, cams)).empty())
      return named("camera linear prior", q, "camera", o.linear[q].camera, why);
  for (int q = 0; q < o.npoint; ++q)
    if (!(why = check_point(o.point[q], lay)).empty()) return named("point prior", q, "point", o.point[q].point, why);
  return {};
}

PriorTerms::PriorTerms(const PriorOptions &o, const Layout &lay) : lay_(lay) {
  std::string unused;
  const auto common = [&](Term &t, const auto &pr) {
    t.L = sqrt_information(pr.weight, t.dim);
    prior_loss(pr.loss, pr.loss_scale, &t.loss, &unused);
    terms_.push_back(std::move(t));
  };
  for (int q = 0; q < o.ncamera; ++q) {
    Term t;
    t.kind = Kind::Camera;
    t.index = q;
    t.target = o.camera[q].camera;
    t.dim = o.camera[q].dim;
    t.cb = &o.camera[q];
    common(t, o.camera[q]);
  }
  for (int q = 0; q < o.nlinear; ++q) {
    const sba_camera_linear_prior &pr = o.linear[q];
    Term t;
    t.kind = Kind::Linear;
    t.index = q;
    t.target = pr.camera;
    t.dim = pr.k;
    t.params.assign(pr.params, pr.params + pr.k);
    t.mean.assign(pr.mean, pr.mean + pr.k);
    common(t, pr);
  }
  for (int q = 0; q < o.npoint; ++q) {
    Term t;
    t.kind = Kind::Point;
    t.index = q;
    t.target = o.point[q].point;
    t.dim = lay.pnp;
    t.mean.assign(o.point[q].mean, o.point[q].mean + lay.pnp);
    common(t, o.point[q]);
  }
}

// r, unweighted: the callback's, or the constrained parameters minus their mean.
void PriorTerms::residual(const Term &t, const double *p, double *r) const {
  const double *b = block(t, p);
  if (t.kind == Kind::Camera) {
    t.cb->func(t.target, b, r, t.cb->data);
    return;
  }
  for (int q = 0; q < t.dim; ++q) r[q] = b[t.kind == Kind::Linear ? t.params[size_t(q)] : q] - t.mean[size_t(q)];
}

// dr/d(the block), dim x width, row-major: the callback's (or its forward differences), or
// the selection of the constrained parameters.
void PriorTerms::jacobian(const Term &t, const double *p, double *J) const {
  const int w = width(t);
  std::fill(J, J + t.dim * w, 0.0);
  if (t.kind == Kind::Point) {
    for (int q = 0; q < t.dim; ++q) J[q * w + q] = 1.0;
  } else if (t.kind == Kind::Linear) {
    for (int q = 0; q < t.dim; ++q) J[q * w + t.params[size_t(q)]] = 1.0;
  } else if (t.cb->jacf) {
    t.cb->jacf(t.target, block(t, p), J, t.cb->data);
  } else {
    std::vector<double> a(block(t, p), block(t, p) + w), r0(static_cast<size_t>(t.dim)), r1(r0.size());
    t.cb->func(t.target, a.data(), r0.data(), t.cb->data);
    for (int c = 0; c < w; ++c) {
      const double saved = a[size_t(c)], d = fd_step(saved);
      a[size_t(c)] = saved + d;
      t.cb->func(t.target, a.data(), r1.data(), t.cb->data);
      a[size_t(c)] = saved;
      for (int q = 0; q < t.dim; ++q) J[q * w + c] = (r1[size_t(q)] - r0[size_t(q)]) / d;
    }
  }
}

// y = L r (L upper triangular).
void PriorTerms::weigh(const Term &t, const double *r, double *y) const {
  for (int a = 0; a < t.dim; ++a) {
    double s = 0.0;
    for (int b = a; b < t.dim; ++b) s += t.L[size_t(a) * t.dim + b] * r[b];
    y[a] = s;
  }
}

bool PriorTerms::cost(const double *p, const Logger &log, const char *where, PriorCost *c) const {
  *c = PriorCost{};
  std::vector<double> r, y;
  for (const Term &t : terms_) {
    r.resize(size_t(t.dim));
    y.resize(r.size());
    residual(t, p, r.data());
    weigh(t, r.data(), y.data());
    double s = 0.0;
    for (double v : y) s += v * v;
    if (!std::isfinite(s)) {
      const char *what = t.kind == Kind::Camera ? "camera prior" : t.kind == Kind::Linear ? "camera linear prior" : "point prior";
      log.error("sba: the residual of %s %d is not finite%s", what, t.index, where);
      return false;
    }
    c->sq += s;
    c->cost += t.loss.rho(s);
  }
  return true;
}

// One prior's blocks into G (width x width) and g (width); returns its reweighted ||y||^2.
double PriorTerms::add_term(const Term &t, const double *p, double *G, double *g) const {
  const int w = width(t), d = t.dim;
  std::vector<double> r(static_cast<size_t>(d)), y(r.size()), J(r.size() * size_t(w)), LJ(J.size()), col(r.size());
  residual(t, p, r.data());
  weigh(t, r.data(), y.data());
  jacobian(t, p, J.data());
  if (t.kind == Kind::Camera && lay_.cams.any_held())
    for (int c = 0; c < w; ++c)
      if (lay_.cams.held(t.target, c))
        for (int q = 0; q < d; ++q) J[size_t(q) * w + c] = 0.0;
  for (int c = 0; c < w; ++c) {  // L J, column by column
    for (int q = 0; q < d; ++q) r[size_t(q)] = J[size_t(q) * w + c];
    weigh(t, r.data(), col.data());
    for (int q = 0; q < d; ++q) LJ[size_t(q) * w + c] = col[size_t(q)];
  }
  double s = 0.0;
  for (double v : y) s += v * v;
  const double rw = t.loss.robust() ? std::sqrt(t.loss.weight(s)) : 1.0;
  for (double &v : y) v *= rw;
  for (double &v : LJ) v *= rw;
  for (int a = 0; a < w; ++a) {
    for (int q = 0; q < d; ++q) g[a] -= LJ[size_t(q) * w + a] * y[size_t(q)];
    for (int b = 0; b < w; ++b)
      for (int q = 0; q < d; ++q) G[a * w + b] += LJ[size_t(q) * w + a] * LJ[size_t(q) * w + b];
  }
  double sr = 0.0;
  for (double v : y) sr += v * v;
  return sr;
}

double PriorTerms::add_normal_equations(const double *p, double *U, double *V, double *ea, double *eb) const {
  double sq = 0.0;
  const i64 c2 = i64(lay_.cnp) * lay_.cnp, p2 = i64(lay_.pnp) * lay_.pnp;
  for (const Term &t : terms_) {
    if (t.kind == Kind::Point)
      sq += add_term(t, p, V + t.target * p2, eb + i64(t.target) * lay_.pnp);
    else
      sq += add_term(t, p, U + t.target * c2, ea + i64(t.target) * lay_.cnp);
  }
  return sq;
}

// One callback prior's Jacobian against central differences; *rows counts its rows.
i64 PriorTerms::check_term(const Term &t, const double *p, const Logger &log, i64 *rows) const {
  const int w = width(t), d = t.dim;
  std::vector<double> rp(static_cast<size_t>(d)), rm(rp.size()), r0(rp.size()), J(rp.size() * size_t(w)),
      num(J.size()), a(block(t, p), block(t, p) + w);
  t.cb->jacf(t.target, a.data(), J.data(), t.cb->data);
  t.cb->func(t.target, a.data(), r0.data(), t.cb->data);
  std::vector<double> h(static_cast<size_t>(w));
  for (int c = 0; c < w; ++c) {
    const double saved = a[size_t(c)];
    h[size_t(c)] = fd_step(saved);
    a[size_t(c)] = saved + h[size_t(c)];
    t.cb->func(t.target, a.data(), rp.data(), t.cb->data);
    a[size_t(c)] = saved - h[size_t(c)];
    t.cb->func(t.target, a.data(), rm.data(), t.cb->data);
    a[size_t(c)] = saved;
    for (int q = 0; q < d; ++q) num[size_t(q) * w + c] = (rp[size_t(q)] - rm[size_t(q)]) / (2.0 * h[size_t(c)]);
  }
  i64 bad = 0;
  for (int q = 0; q < d; ++q) {
    ++*rows;
    const double *ar = J.data() + size_t(q) * w, *nr = num.data() + size_t(q) * w;
    double rowmax = 0.0;
    for (int c = 0; c < w; ++c) rowmax = std::max(rowmax, std::fabs(nr[c]));
    const double f = std::fabs(r0[size_t(q)]) + 1.0;
    int worst = -1;
    double worst_err = 0.0;
    for (int c = 0; c < w; ++c) {
      if (lay_.cams.held(t.target, c)) continue;
      const double err = std::fabs(ar[c] - nr[c]);
      const double tol = 1e-4 * std::max(std::fabs(ar[c]), std::fabs(nr[c])) + 1e-6 * rowmax + 1e2 * DBL_EPSILON * f / h[size_t(c)];
      if (!(err <= tol) && (worst < 0 || err > worst_err)) worst = c, worst_err = err;
    }
    if (worst < 0) continue;
    ++bad;
    log.report("camera prior %d (camera %d): gradient of residual entry %d is probably wrong: d/d(parameter %d) "
               "analytic %.8g, finite differences %.8g",
               t.index, t.target, q, worst, ar[worst], nr[worst]);
  }
  return bad;
}

i64 PriorTerms::check_jacobians(const double *p, const Logger &log) const {
  i64 bad = 0, rows = 0;
  for (const Term &t : terms_)
    if (t.kind == Kind::Camera && t.cb->jacf) bad += check_term(t, p, log, &rows);
  if (rows == 0) return 0;
  if (bad == 0)
    log.report("sba: Jacobian check: all %lld gradients of the camera priors agree with finite differences",
               static_cast<long long>(rows));
  else
    log.report("sba: Jacobian check: %lld of %lld gradients of the camera priors look wrong",
               static_cast<long long>(bad), static_cast<long long>(rows));
  return bad;
}

}  // namespace sba
