/* SPDX-License-Identifier: BSD-3-Clause */
// A failed call into AMD or CHOLMOD as an exception, so that a solve reports it as what it
// was. Out of memory is a resource failure (std::bad_alloc, reported as such). Any other
// failure is an internal error: the solvers hand these libraries matrices that are valid by
// construction, so an invalid-input or overflow status means a bug of ours, and the message
// names the routine and the library's status code (std::runtime_error, which the drivers
// report as "internal error: ...") rather than blaming the memory.
#ifndef SBA_SRC_SUITESPARSE_STATUS_H
#define SBA_SRC_SUITESPARSE_STATUS_H

#include <new>
#include <stdexcept>
#include <string>

extern "C" {
#include <suitesparse/amd.h>
#include <suitesparse/cholmod.h>
}

namespace sba {

// AMD's name for an amd_order status.
inline const char *amd_status_name(int status) {
  switch (status) {
    case AMD_OK: return "ok";
    case AMD_OK_BUT_JUMBLED: return "ok but jumbled";
    case AMD_OUT_OF_MEMORY: return "out of memory";
    case AMD_INVALID: return "invalid input";
    default: return "unknown status";
  }
}

// CHOLMOD's name for a cholmod_common status.
inline const char *cholmod_status_name(int status) {
  switch (status) {
    case CHOLMOD_OK: return "ok";
    case CHOLMOD_NOT_INSTALLED: return "method not installed";
    case CHOLMOD_OUT_OF_MEMORY: return "out of memory";
    case CHOLMOD_TOO_LARGE: return "integer overflow";
    case CHOLMOD_INVALID: return "invalid input";
    case CHOLMOD_GPU_PROBLEM: return "GPU error";
    case CHOLMOD_NOT_POSDEF: return "not positive definite";
    case CHOLMOD_DSMALL: return "tiny diagonal";
    default: return "unknown status";
  }
}

// Throws for a failed AMD call `routine` that returned `status`.
[[noreturn]] inline void throw_amd_failure(const char *routine, int status) {
  if (status == AMD_OUT_OF_MEMORY) throw std::bad_alloc();
  throw std::runtime_error(std::string("AMD ") + routine + " failed with status " +
                           std::to_string(status) + " (" + amd_status_name(status) + ")");
}

// Throws for a failed CHOLMOD call `routine` that left `status` in its cholmod_common.
[[noreturn]] inline void throw_cholmod_failure(const char *routine, int status) {
  if (status == CHOLMOD_OUT_OF_MEMORY) throw std::bad_alloc();
  throw std::runtime_error(std::string("CHOLMOD ") + routine + " failed with status " +
                           std::to_string(status) + " (" + cholmod_status_name(status) + ")");
}

}  // namespace sba

#endif
