// SPDX-License-Identifier: BSD-3-Clause
#include "kernels.h"

#include "isa.h"

#define SBA_KERNELS_NS portable
#include "kernels_impl.h"

namespace sba {

#if defined(SBA_HAVE_AVX2_BUILD)
namespace avx2 {
std::unique_ptr<Kernels> make_kernels(const Layout &lay, int threads, i64 max_packed);
}
#endif

std::unique_ptr<Kernels> make_kernels(const Layout &lay, int threads, i64 max_packed) {
#if defined(SBA_HAVE_AVX2_BUILD)
  if (use_avx2_build()) return avx2::make_kernels(lay, threads, max_packed);
#endif
  return portable::make_kernels(lay, threads, max_packed);
}

}  // namespace sba
