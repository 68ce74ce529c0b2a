// SPDX-License-Identifier: BSD-3-Clause
// The mapped assembly built for CPUs with AVX2 and FMA (compiled with -mavx2 -mfma; see
// mapped_schur_impl.h). Only reached after a run-time check of the CPU.
#define SBA_KERNELS_NS avx2
#include "mapped_schur_impl.h"
