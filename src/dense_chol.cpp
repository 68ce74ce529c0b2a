// SPDX-License-Identifier: BSD-3-Clause
// The own dense Cholesky's portable build, and the choice between it and the AVX2 build
// (dense_chol_avx2.cpp).
#include "dense_factorization.h"
#include "isa.h"

#define SBA_DENSE_CHOL_NS portable
#include "dense_chol_impl.h"

namespace sba {

#if defined(SBA_HAVE_AVX2_BUILD)
namespace avx2 {
bool dense_cholesky(ThreadPool &pool, double *S, i64 n, i64 ld, i64 nrhs);
}
#endif

DenseCholesky own_dense_cholesky() {
#if defined(SBA_HAVE_AVX2_BUILD)
  if (use_avx2_build()) return avx2::dense_cholesky;
#endif
  return portable::dense_cholesky;
}

}  // namespace sba
