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

i64 check_jacobian(const Layout &lay, Model &model, double *p, const Logger &log) {
  const int mnp = lay.mnp, cnp = lay.cnp, pnp = lay.pnp, jblk = lay.jblk();
  const i64 nobs = lay.nvis * mnp;
  std::vector<double> hx(static_cast<size_t>(nobs)), hp(hx.size()), hm(hx.size());
  std::vector<double> ana(size_t(lay.nvis * jblk)), num(ana.size(), 0.0);
  std::vector<double> step_of(size_t(std::max(lay.n, lay.m)));
  model.eval(p, hx.data());
  model.jacobian(p, ana.data());

  // Central differences, all free cameras (or points) perturbed together in parameter l:
  // exact grouping, since projection (i,j) depends only on camera j and point i.
  auto difference = [&](bool cams, int l) {
    const int first = cams ? lay.mcon : lay.ncon, last = cams ? lay.m : lay.n;
    auto at = [&](int o) -> double & { return p[cams ? lay.a_off(o) + l : lay.b_off(o) + l]; };
    std::vector<double> saved(static_cast<size_t>(last));
    for (int o = first; o < last; ++o) {
      saved[o] = at(o);
      step_of[o] = fd_step(saved[o]);
      at(o) = saved[o] + step_of[o];
    }
    model.eval(p, hp.data());
    for (int o = first; o < last; ++o) at(o) = saved[o] - step_of[o];
    model.eval(p, hm.data());
    for (int o = first; o < last; ++o) at(o) = saved[o];
    for (int i = 0; i < lay.n; ++i)
      for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
        const int o = cams ? lay.colidx[k] : i;
        if (o < first) continue;
        for (int r = 0; r < mnp; ++r) {
          const i64 q = i64(k) * mnp + r;
          const i64 e = i64(k) * jblk + (cams ? r * cnp + l : mnp * cnp + r * pnp + l);
          num[size_t(e)] = (hp[q] - hm[q]) / (2.0 * step_of[o]);
        }
      }
  };
  for (int l = 0; l < cnp && lay.free_cams() > 0; ++l) difference(true, l);
  for (int l = 0; l < pnp && lay.free_pts() > 0; ++l) difference(false, l);

  i64 bad = 0, rows = 0;
  for (int i = 0; i < lay.n; ++i)
    for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
      const int j = lay.colidx[k];
      const bool cf = lay.cam_free(j), pf = lay.pt_free(i);
      if (!cf && !pf) continue;
      for (int r = 0; r < mnp; ++r) {
        ++rows;
        // Columns of this measurement row that are free, as (offset in the block, is camera).
        double rowmax = 0.0;
        auto each = [&](auto fn) {
          for (int c = 0; cf && c < cnp; ++c) fn(r * cnp + c, true, c);
          for (int c = 0; pf && c < pnp; ++c) fn(mnp * cnp + r * pnp + c, false, c);
        };
        each([&](int off, bool, int) {
          rowmax = std::max(rowmax, std::fabs(num[size_t(i64(k) * jblk + off)]));
        });
        // Tolerance: relative agreement, plus the rounding noise of a central difference of
        // a value of size |f| with that column's step.
        const double f = std::fabs(hx[size_t(i64(k) * mnp + r)]) + 1.0;
        int worst = -1;
        bool worst_cam = false;
        double worst_err = 0.0;
        each([&](int off, bool cam, int c) {
          const double a = ana[size_t(i64(k) * jblk + off)], nm = num[size_t(i64(k) * jblk + off)];
          const double h = fd_step(cam ? p[lay.a_off(j) + c] : p[lay.b_off(i) + c]);
          const double err = std::fabs(a - nm);
          const double tol = 1e-4 * std::max(std::fabs(a), std::fabs(nm)) + 1e-6 * rowmax +
                             1e2 * DBL_EPSILON * f / h;
          if (!(err <= tol) && (worst < 0 || err > worst_err)) {
            worst = c;
            worst_cam = cam;
            worst_err = err;
          }
        });
        if (worst < 0) continue;
        ++bad;
        const int off = worst_cam ? r * cnp + worst : mnp * cnp + r * pnp + worst;
        log.report("gradient %lld (element %d of the projection of point %d on camera %d) is "
                   "probably wrong: d/d(%s %d parameter %d) analytic %.8g, finite differences %.8g",
                   static_cast<long long>(i64(k) * mnp + r), r, i, j,
                   worst_cam ? "camera" : "point", worst_cam ? j : i, worst,
                   ana[size_t(i64(k) * jblk + off)], num[size_t(i64(k) * jblk + off)]);
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
