/* SPDX-License-Identifier: BSD-3-Clause */
// A counting replacement of the global operator new/delete, for tests that check that a
// failed solve gives back every allocation it made, and that want the k-th allocation to fail.
// The executable's operator new interposes the one of libstdc++ for libsba.so too, so the
// library's allocations are counted. Include this header in exactly ONE source file of a
// program (it defines the replacement operators). Under a sanitizer, which replaces the
// operators itself and tracks leaks on its own, nothing is replaced and the counters stay 0.
#ifndef SBA_TESTS_COUNTING_NEW_H
#define SBA_TESTS_COUNTING_NEW_H

#include <atomic>
#include <cstddef>
#include <cstdlib>
#include <new>

#include "sanitized.h"

namespace faults {
inline std::atomic<long> g_live_news{0};       // allocations not yet given back
inline std::atomic<long> g_news_total{0};      // allocations ever made
inline std::atomic<long> g_fail_countdown{0};  // > 0: the allocation that takes it to 0 fails
}  // namespace faults

#ifndef SBA_TEST_SANITIZED
namespace faults {
inline bool injected_failure() {
  return g_fail_countdown.load(std::memory_order_relaxed) > 0 && g_fail_countdown.fetch_sub(1) == 1;
}
inline void *counted_alloc(std::size_t size) {
  g_news_total.fetch_add(1, std::memory_order_relaxed);
  if (injected_failure()) return nullptr;
  void *p = std::malloc(size ? size : 1);
  if (p) g_live_news.fetch_add(1, std::memory_order_relaxed);
  return p;
}
inline void *counted_aligned_alloc(std::size_t size, std::size_t align) {
  g_news_total.fetch_add(1, std::memory_order_relaxed);
  if (injected_failure()) return nullptr;
  void *p = nullptr;
  if (posix_memalign(&p, align < sizeof(void *) ? sizeof(void *) : align, size ? size : 1) != 0)
    return nullptr;
  g_live_news.fetch_add(1, std::memory_order_relaxed);
  return p;
}
inline void counted_free(void *p) {
  if (!p) return;
  g_live_news.fetch_sub(1, std::memory_order_relaxed);
  std::free(p);
}
}  // namespace faults

using faults::counted_alloc;
using faults::counted_aligned_alloc;
using faults::counted_free;

void *operator new(std::size_t size) {
  if (void *p = counted_alloc(size)) return p;
  throw std::bad_alloc();
}
void *operator new[](std::size_t size) {
  if (void *p = counted_alloc(size)) return p;
  throw std::bad_alloc();
}
void *operator new(std::size_t size, const std::nothrow_t &) noexcept { return counted_alloc(size); }
void *operator new[](std::size_t size, const std::nothrow_t &) noexcept { return counted_alloc(size); }
void *operator new(std::size_t size, std::align_val_t al) {
  if (void *p = counted_aligned_alloc(size, std::size_t(al))) return p;
  throw std::bad_alloc();
}
void *operator new[](std::size_t size, std::align_val_t al) {
  if (void *p = counted_aligned_alloc(size, std::size_t(al))) return p;
  throw std::bad_alloc();
}
void *operator new(std::size_t size, std::align_val_t al, const std::nothrow_t &) noexcept {
  return counted_aligned_alloc(size, std::size_t(al));
}
void *operator new[](std::size_t size, std::align_val_t al, const std::nothrow_t &) noexcept {
  return counted_aligned_alloc(size, std::size_t(al));
}
void operator delete(void *p) noexcept { counted_free(p); }
void operator delete[](void *p) noexcept { counted_free(p); }
void operator delete(void *p, std::size_t) noexcept { counted_free(p); }
void operator delete[](void *p, std::size_t) noexcept { counted_free(p); }
void operator delete(void *p, const std::nothrow_t &) noexcept { counted_free(p); }
void operator delete[](void *p, const std::nothrow_t &) noexcept { counted_free(p); }
void operator delete(void *p, std::align_val_t) noexcept { counted_free(p); }
void operator delete[](void *p, std::align_val_t) noexcept { counted_free(p); }
void operator delete(void *p, std::size_t, std::align_val_t) noexcept { counted_free(p); }
void operator delete[](void *p, std::size_t, std::align_val_t) noexcept { counted_free(p); }
void operator delete(void *p, std::align_val_t, const std::nothrow_t &) noexcept { counted_free(p); }
void operator delete[](void *p, std::align_val_t, const std::nothrow_t &) noexcept { counted_free(p); }
#endif

#endif
