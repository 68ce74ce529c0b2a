// SPDX-License-Identifier: BSD-3-Clause
// The itmax == 0 mode of the drivers: compare the caller's analytic Jacobian with central
// differences, entry by entry, over the free parameters only (fixed cameras and points are
// never differentiated, so they cannot raise false alarms as they did in 1.6).
#include "jacobian_check.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <vector>

namespace sba {
namespace {

// The Jacobian of the free parameters by central differences, in the callbacks' block layout
// (A_ij then B_ij per projection; the entries of fixed cameras and points stay 0).
class CentralDifferences {
 public:
  CentralDifferences(const Layout &lay, Model &model, double *p)
      : lay_(lay), model_(model), p_(p), hp_(size_t(lay.nvis * lay.mnp)), hm_(hp_.size()),
        step_of_(size_t(std::max(lay.n, lay.m))) {}

  std::vector<double> jacobian() {
    std::vector<double> num(size_t(lay_.nvis * lay_.jblk()), 0.0);
    for (int l = 0; l < lay_.cnp && lay_.free_cams() > 0; ++l) column(true, l, num);
    for (int l = 0; l < lay_.pnp && lay_.free_pts() > 0; ++l) column(false, l, num);
    return num;
  }

 private:
  // Parameter l of every free camera (or point), all perturbed together: exact grouping,
  // since projection (i,j) depends only on camera j and point i.
  void column(bool cams, int l, std::vector<double> &num) {
    const Layout &lay = lay_;
    const int mnp = lay.mnp, cnp = lay.cnp, pnp = lay.pnp, jblk = lay.jblk();
    const int first = cams ? lay.mcon : lay.ncon, last = cams ? lay.m : lay.n;
    auto at = [&](int o) -> double & { return p_[cams ? lay.a_off(o) + l : lay.b_off(o) + l]; };
    std::vector<double> saved(static_cast<size_t>(last));
    for (int o = first; o < last; ++o) {
      saved[o] = at(o);
      step_of_[o] = fd_step(saved[o]);
      at(o) = saved[o] + step_of_[o];
    }
    model_.eval(p_, hp_.data());
    for (int o = first; o < last; ++o) at(o) = saved[o] - step_of_[o];
    model_.eval(p_, hm_.data());
    for (int o = first; o < last; ++o) at(o) = saved[o];
    for (int i = 0; i < lay.n; ++i)
      for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
        const int o = cams ? lay.colidx[k] : i;
        if (o < first) continue;
        for (int r = 0; r < mnp; ++r) {
          const i64 q = i64(k) * mnp + r;
          const i64 e = i64(k) * jblk + (cams ? r * cnp + l : mnp * cnp + r * pnp + l);
          num[size_t(e)] = (hp_[q] - hm_[q]) / (2.0 * step_of_[o]);
        }
      }
  }

  const Layout &lay_;
  Model &model_;
  double *p_;
  std::vector<double> hp_, hm_, step_of_;
};

// The free entry of a measurement row that disagrees most with its difference, beyond the
// tolerance; column < 0 when every entry agrees.
struct Suspect {
  int column = -1;  // of the camera's or the point's parameters
  bool camera = false;
};

// Row r of projection k (point i on camera j): ana and num its entries (analytic and
// differences, in the block layout), f = |f(p)| + 1 of its value.
Suspect worst_entry(const Layout &lay, const double *p, const double *ana, const double *num, double f, int k,
                    int i, int j, int r) {
  const int mnp = lay.mnp, cnp = lay.cnp, pnp = lay.pnp, jblk = lay.jblk();
  const bool cf = lay.cam_free(j), pf = lay.pt_free(i);
  // Columns of this measurement row that are free, as (offset in the block, is camera).
  double rowmax = 0.0;
  auto each = [&](auto fn) {
    for (int c = 0; cf && c < cnp; ++c) fn(r * cnp + c, true, c);
    for (int c = 0; pf && c < pnp; ++c) fn(mnp * cnp + r * pnp + c, false, c);
  };
  each([&](int off, bool, int) { rowmax = std::max(rowmax, std::fabs(num[size_t(i64(k) * jblk + off)])); });
  // Tolerance: relative agreement, plus the rounding noise of a central difference of a value
  // of size f with that column's step.
  Suspect worst;
  double worst_err = 0.0;
  each([&](int off, bool cam, int c) {
    const double a = ana[size_t(i64(k) * jblk + off)], nm = num[size_t(i64(k) * jblk + off)];
    const double h = fd_step(cam ? p[lay.a_off(j) + c] : p[lay.b_off(i) + c]);
    const double err = std::fabs(a - nm);
    const double tol =
        1e-4 * std::max(std::fabs(a), std::fabs(nm)) + 1e-6 * rowmax + 1e2 * DBL_EPSILON * f / h;
    if (!(err <= tol) && (worst.column < 0 || err > worst_err)) {
      worst = {c, cam};
      worst_err = err;
    }
  });
  return worst;
}

}  // namespace

i64 check_jacobian(const Layout &lay, Model &model, double *p, const Logger &log) {
  const int mnp = lay.mnp, cnp = lay.cnp, pnp = lay.pnp, jblk = lay.jblk();
  std::vector<double> hx(size_t(lay.nvis * mnp)), ana(size_t(lay.nvis * jblk));
  model.eval(p, hx.data());
  model.jacobian(p, ana.data());
  const std::vector<double> num = CentralDifferences(lay, model, p).jacobian();

  i64 bad = 0, rows = 0;
  for (int i = 0; i < lay.n; ++i)
    for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
      const int j = lay.colidx[k];
      if (!lay.cam_free(j) && !lay.pt_free(i)) continue;
      for (int r = 0; r < mnp; ++r) {
        ++rows;
        const double f = std::fabs(hx[size_t(i64(k) * mnp + r)]) + 1.0;
        const Suspect s = worst_entry(lay, p, ana.data(), num.data(), f, k, i, j, r);
        if (s.column < 0) continue;
        ++bad;
        const int off = s.camera ? r * cnp + s.column : mnp * cnp + r * pnp + s.column;
        log.report("gradient %lld (element %d of the projection of point %d on camera %d) is "
                   "probably wrong: d/d(%s %d parameter %d) analytic %.8g, finite differences %.8g",
                   static_cast<long long>(i64(k) * mnp + r), r, i, j, s.camera ? "camera" : "point",
                   s.camera ? j : i, s.column, ana[size_t(i64(k) * jblk + off)],
                   num[size_t(i64(k) * jblk + off)]);
      }
    }
  if (bad == 0)
    log.report("sba: Jacobian check: all %lld gradients agree with finite differences",
               static_cast<long long>(rows));
  else
    log.report("sba: Jacobian check: %lld of %lld gradients look wrong",
               static_cast<long long>(bad), static_cast<long long>(rows));
  return bad;
}

}  // namespace sba
