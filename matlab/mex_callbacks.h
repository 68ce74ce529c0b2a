// SPDX-License-Identifier: BSD-3-Clause
// The MEX gateway's callbacks: the library's proj/projac, log and progress callbacks bridged to
// the host's functions (or to NAME@LIBRARY's), with every failure recorded in the Gateway and
// answered with NaN, so that nothing of the host's crosses the library.
#ifndef SBA_MATLAB_MEX_CALLBACKS_H
#define SBA_MATLAB_MEX_CALLBACKS_H

#include <vector>

#include "mex_common.h"

namespace sba_mex __attribute__((visibility("hidden"))) {

// The trial call on camera 0 and point 0: wrong sizes and failing callbacks are reported as
// argument errors before the solve.
void trial_call(Gateway &g);

// Runs the simple driver of g.reftype on p (the part of p0 it refines); the driver's return
// value, info filled.
int solve(Gateway &g, std::vector<double> &p, double info[SBA_INFOSZ]);

}  // namespace sba_mex

#endif
