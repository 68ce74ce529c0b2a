/* SPDX-License-Identifier: BSD-3-Clause */
// A driver call of the C API parsed: one entry point's C arguments as one value, built the
// same way by every entry point.
#ifndef SBA_SRC_DRIVER_ARGS_H
#define SBA_SRC_DRIVER_ARGS_H

#include "callback_adapters.h"
#include "layout.h"
#include "sba_export.h"

namespace sba {

// One entry point's arguments. The entry points build it with the problem builders below
// (one per prototype shape) and then solving() or estimating(), never field by field.
struct DriverArgs {
  const char *name = nullptr;  // the entry point as messages name it
  Mode mode = Mode::MotStr;
  int n = 0, ncon = 0, m = 0, mcon = 0, cnp = 0, pnp = 0, mnp = 0;
  char *vmask = nullptr;
  bool by_pairs = false;                // the _vis entry points: pairs instead of vmask
  const sba_visibility *vis = nullptr;
  double *p = nullptr, *x = nullptr, *covx = nullptr;
  UserCallbacks callbacks;
  int itmax = 0, verbose = 0;
  const double *opts = nullptr;
  double *info = nullptr;
  const sba_ext_options *ext = nullptr;

  // The levmar entry points' controls.
  DriverArgs &solving(const UserCallbacks &cb, int itmax_arg, int verbose_arg,
                      const double *opts_arg, double *info_arg, const sba_ext_options *ext_arg) {
    callbacks = cb;
    itmax = itmax_arg;
    verbose = verbose_arg;
    opts = opts_arg;
    info = info_arg;
    ext = ext_arg;
    return *this;
  }
  // The covariance entry points': no iterations and no opts or info, but itmax = 1, since
  // itmax = 0 would ask for a Jacobian check.
  DriverArgs &estimating(const UserCallbacks &cb, const sba_ext_options *ext_arg) {
    return solving(cb, 1, 0, nullptr, nullptr, ext_arg);
  }
};

// The problem builders: one per shape of prototype, their parameters in the prototype's
// order, so that an entry point passes its own arguments as they come. The sizes a mode has
// no use for stay 0.
DriverArgs motstr_problem(const char *name, int n, int ncon, int m, int mcon, char *vmask,
                          double *p, int cnp, int pnp, double *x, double *covx, int mnp);
DriverArgs mot_problem(const char *name, int n, int m, int mcon, char *vmask, double *p, int cnp,
                       double *x, double *covx, int mnp);
DriverArgs str_problem(const char *name, int n, int ncon, int m, char *vmask, double *p, int pnp,
                       double *x, double *covx, int mnp);
// A problem of the pairs entry points: one of the builders above, vis for its vmask.
DriverArgs by_pairs(DriverArgs a, const sba_visibility *vis);

}  // namespace sba

#endif
