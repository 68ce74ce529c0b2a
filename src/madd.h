/* SPDX-License-Identifier: BSD-3-Clause */
// madd, shared by the code the library builds twice (portable, and with AVX2 and FMA): the
// block kernels (kernels_impl.h) and the own dense Cholesky (dense_chol_impl.h).
#ifndef SBA_SRC_MADD_H
#define SBA_SRC_MADD_H

namespace sba {
// Internal linkage: each build's translation units get the definition their flags select, and
// no two builds share a symbol.
namespace {

// a * b + c, rounded as the compiler rounds y += s * x in a loop (kernels_impl.h's axpy): one
// fused operation where the target has FMA, else a product then a sum. Spelled out where a sum of products is kept in locals:
// there the compiler may otherwise fuse either product (x0 y0 + x1 y1 has two contractions).
inline __attribute__((always_inline)) double madd(double a, double b, double c) {
#ifdef __FMA__
  return __builtin_fma(a, b, c);
#else
  return a * b + c;
#endif
}

}  // namespace
}  // namespace sba

#endif
