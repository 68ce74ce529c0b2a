// SPDX-License-Identifier: BSD-3-Clause
// The MEX gateway's arguments: sba 1.6's argument list (docs/mex.md, "Call") read into a
// Gateway, every check made before any solve.
#ifndef SBA_MATLAB_MEX_ARGS_H
#define SBA_MATLAB_MEX_ARGS_H

#include <string>

#include "mex_common.h"

namespace sba_mex __attribute__((visibility("hidden"))) {

// Fills g from prhs; raises bad_arg (an ArgError) on the first bad argument. *warning gets
// the text of a warning to give once the call is over (short opts), if any.
void parse(Gateway &g, int nrhs, const mxArray *prhs[], std::string *warning);

}  // namespace sba_mex

#endif
