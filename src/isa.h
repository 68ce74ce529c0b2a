/* SPDX-License-Identifier: BSD-3-Clause */
// Which of the library's builds of its hot code runs: the block kernels (kernels.cpp,
// kernels_avx2.cpp) and the own dense Cholesky (dense_chol.cpp, dense_chol_avx2.cpp) are
// each compiled for any x86-64 and, where the compiler can, for AVX2 with FMA.
#ifndef SBA_SRC_ISA_H
#define SBA_SRC_ISA_H

namespace sba {

// True where the AVX2 builds exist and this CPU runs them. SBA_KERNELS=portable forces the
// portable builds (to compare the two, or to reproduce results bit for bit on another CPU:
// FMA rounds differently).
bool use_avx2_build();

}  // namespace sba

#endif
