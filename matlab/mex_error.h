// SPDX-License-Identifier: BSD-3-Clause
// How the MEX gateway's parts report a bad argument, free of the host's API (mex.h), so that
// the checks written over plain values (mex_options.h) can be fuzzed without a host.
#ifndef SBA_MATLAB_MEX_ERROR_H
#define SBA_MATLAB_MEX_ERROR_H

#include <string>

namespace sba_mex __attribute__((visibility("hidden"))) {

constexpr int kMaxMessage = 2048;

std::string format(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

// A bad argument: thrown while parsing (before any solve), caught in run_gateway().
struct ArgError {
  std::string id, message;
};

// Throws ArgError{"sba:" + id, message}.
[[noreturn]] void bad_arg(const std::string &id, const std::string &message);

}  // namespace sba_mex

#endif
