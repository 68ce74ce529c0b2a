#include "kernels.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>

#define SBA_KERNELS_NS portable
#include "kernels_impl.h"

namespace sba {

#if defined(SBA_HAVE_AVX2_KERNELS)
namespace avx2 {
std::unique_ptr<Kernels> make_kernels(const Layout &lay, int threads);
}
#endif

std::unique_ptr<Kernels> make_kernels(const Layout &lay, int threads) {
#if defined(SBA_HAVE_AVX2_KERNELS)
  // SBA_KERNELS=portable forces the baseline build (to compare the two, or to reproduce
  // results bit for bit on another CPU: FMA rounds differently).
  const char *force = std::getenv("SBA_KERNELS");
  if (!(force && std::strcmp(force, "portable") == 0) && __builtin_cpu_supports("avx2") &&
      __builtin_cpu_supports("fma"))
    return avx2::make_kernels(lay, threads);
#endif
  return portable::make_kernels(lay, threads);
}

}  // namespace sba
