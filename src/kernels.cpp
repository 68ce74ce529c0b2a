// SPDX-License-Identifier: BSD-3-Clause
#include "kernels.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>

#include "dense_factorization.h"

#define SBA_KERNELS_NS portable
#include "kernels_impl.h"

namespace sba {

#if defined(SBA_HAVE_AVX2_KERNELS)
namespace avx2 {
std::unique_ptr<Kernels> make_kernels(const Layout &lay, int threads);
bool dense_cholesky(ThreadPool &pool, double *S, i64 n, i64 ld, i64 nrhs);
}
#endif

namespace {

// Whether to run the AVX2 build. SBA_KERNELS=portable forces the baseline build (to compare
// the two, or to reproduce results bit for bit on another CPU: FMA rounds differently).
bool use_avx2_build() {
#if defined(SBA_HAVE_AVX2_KERNELS)
  const char *force = std::getenv("SBA_KERNELS");
  return !(force && std::strcmp(force, "portable") == 0) && __builtin_cpu_supports("avx2") &&
         __builtin_cpu_supports("fma");
#else
  return false;
#endif
}

}  // namespace

std::unique_ptr<Kernels> make_kernels(const Layout &lay, int threads) {
#if defined(SBA_HAVE_AVX2_KERNELS)
  if (use_avx2_build()) return avx2::make_kernels(lay, threads);
#endif
  return portable::make_kernels(lay, threads);
}

DenseCholesky own_dense_cholesky() {
#if defined(SBA_HAVE_AVX2_KERNELS)
  if (use_avx2_build()) return avx2::dense_cholesky;
#endif
  return portable::dense_cholesky;
}

}  // namespace sba
