// SPDX-License-Identifier: BSD-3-Clause
#include "driver_args.h"

namespace sba {

DriverArgs motstr_problem(const char *name, int n, int ncon, int m, int mcon, char *vmask,
                          double *p, int cnp, int pnp, double *x, double *covx, int mnp) {
  DriverArgs a;
  a.name = name;
  a.mode = Mode::MotStr;
  a.n = n;
  a.ncon = ncon;
  a.m = m;
  a.mcon = mcon;
  a.vmask = vmask;
  a.p = p;
  a.cnp = cnp;
  a.pnp = pnp;
  a.x = x;
  a.covx = covx;
  a.mnp = mnp;
  return a;
}

DriverArgs mot_problem(const char *name, int n, int m, int mcon, char *vmask, double *p, int cnp,
                       double *x, double *covx, int mnp) {
  DriverArgs a = motstr_problem(name, n, 0, m, mcon, vmask, p, cnp, 0, x, covx, mnp);
  a.mode = Mode::Mot;
  return a;
}

DriverArgs str_problem(const char *name, int n, int ncon, int m, char *vmask, double *p, int pnp,
                       double *x, double *covx, int mnp) {
  DriverArgs a = motstr_problem(name, n, ncon, m, 0, vmask, p, 0, pnp, x, covx, mnp);
  a.mode = Mode::Str;
  return a;
}

DriverArgs by_pairs(DriverArgs a, const sba_visibility *vis) {
  a.by_pairs = true;
  a.vis = vis;
  return a;
}

}  // namespace sba
