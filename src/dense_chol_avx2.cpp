// SPDX-License-Identifier: BSD-3-Clause
// The own dense Cholesky built for CPUs with AVX2 and FMA (compiled with -mavx2 -mfma; see
// dense_chol_impl.h). Only reached after a run-time check of the CPU (isa.h).
#define SBA_DENSE_CHOL_NS avx2
#include "dense_chol_impl.h"
