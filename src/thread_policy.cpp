// SPDX-License-Identifier: BSD-3-Clause
#include "thread_policy.h"

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstdlib>
#include <thread>

namespace sba {
namespace {

// Projections per thread below which a thread left to the library is not started: each
// kernel of an iteration wakes the pool, and on a small problem that costs more than the
// thread saves. Each thread also holds its stack and the libraries' thread-local storage.
constexpr i64 kProjectionsPerThread = 10000;
// Caps on a count the caller asks for. Threads beyond the hardware's only take turns, and a
// few per hardware thread are allowed (running more threads than cores is how the
// thread-count independence of the results is tested, and harmless at that scale); beyond
// that each one is pure cost: an absurd request (INT_MAX) would otherwise start threads until
// the system refuses, taking seconds and gigabytes. Threads with fewer projections than
// kMinProjectionsPerThread each have nothing to do between their wake-ups.
constexpr int kThreadsPerHardwareThread = 4;
constexpr i64 kMinProjectionsPerThread = 64;

}  // namespace

int hardware_threads() { return std::max(1, int(std::thread::hardware_concurrency())); }

int parse_thread_count(const char *text) {
  if (!text || !*text) return 0;
  errno = 0;
  char *end = nullptr;
  const long v = std::strtol(text, &end, 10);
  const bool whole = end != text && *end == '\0';
  if (!whole || v <= 0) return -1;
  return errno == ERANGE || v > INT_MAX ? INT_MAX : int(v);  // beyond long: huge, capped
}

int fit_threads(i64 nvis, int requested, bool automatic) {
  const int hw = hardware_threads();
  if (automatic) return int(std::clamp<i64>(nvis / kProjectionsPerThread, 1, hw));
  const i64 cap = std::min<i64>(i64(hw) * kThreadsPerHardwareThread,
                                std::max<i64>(1, nvis / kMinProjectionsPerThread));
  return int(std::clamp<i64>(requested, 1, cap));
}

}  // namespace sba
