// SPDX-License-Identifier: BSD-3-Clause
// The block kernels built for CPUs with AVX2 and FMA (compiled with -mavx2 -mfma; see
// kernels_impl.h). Only reached after a run-time check of the CPU.
#define SBA_KERNELS_NS avx2
#include "kernels_impl.h"
