// SPDX-License-Identifier: BSD-3-Clause
#include "mex_error.h"

#include <cstdarg>
#include <cstdio>

namespace sba_mex {

std::string format(const char *fmt, ...) {
  char buf[kMaxMessage];
  va_list ap;
  va_start(ap, fmt);
  std::vsnprintf(buf, sizeof buf, fmt, ap);
  va_end(ap);
  return buf;
}

[[noreturn]] void bad_arg(const std::string &id, const std::string &message) {
  throw ArgError{"sba:" + id, message};
}

}  // namespace sba_mex
