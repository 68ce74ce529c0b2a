// SPDX-License-Identifier: BSD-3-Clause
#include "isa.h"

#include <cstdlib>
#include <cstring>

namespace sba {

bool use_avx2_build() {
#if defined(SBA_HAVE_AVX2_BUILD)
  const char *force = std::getenv("SBA_KERNELS");
  return !(force && std::strcmp(force, "portable") == 0) && __builtin_cpu_supports("avx2") &&
         __builtin_cpu_supports("fma");
#else
  return false;
#endif
}

}  // namespace sba
