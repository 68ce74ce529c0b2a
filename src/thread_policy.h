/* SPDX-License-Identifier: BSD-3-Clause */
// How many threads a solve's pool (parallel.h) gets: the count a caller asks for, read and
// capped, or the library's own choice from the hardware and the problem's size. Whatever the
// count, the results are the same bits.
#ifndef SBA_SRC_THREAD_POLICY_H
#define SBA_SRC_THREAD_POLICY_H

#include "types.h"

namespace sba {

// std::thread::hardware_concurrency, at least 1.
int hardware_threads();

// A thread count given as text (SBA_NUM_THREADS): a positive decimal integer, the whole
// string; counts beyond INT_MAX are just large requests, INT_MAX, capped like any other.
// 0 for null or empty text; -1 for anything else.
int parse_thread_count(const char *text);

// The threads a solve of nvis projections runs. automatic (the count left to the library):
// the hardware's count as far as the problem's size warrants; otherwise `requested`, up to
// caps that keep an absurd request from starting threads until the system refuses.
int fit_threads(i64 nvis, int requested, bool automatic);

}  // namespace sba

#endif
