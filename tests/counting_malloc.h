/* SPDX-License-Identifier: BSD-3-Clause */
// A replacement of malloc and its kin that counts the bytes the process holds from them and the
// most it held since the last reset_peak(): what the library allocates, CHOLMOD's arrays and
// operator new's (which calls malloc) included, for tests that measure a solve's memory.
// glibc's own allocator does the work (__libc_malloc and its kin); a block counts as
// malloc_usable_size says. Include this header in exactly ONE source file of a program. Under
// a sanitizer, which replaces malloc itself, nothing is replaced and the counters stay 0.
#ifndef SBA_TESTS_COUNTING_MALLOC_H
#define SBA_TESTS_COUNTING_MALLOC_H

#include <malloc.h>

#include <atomic>
#include <cerrno>
#include <cstddef>

#include "sanitized.h"

namespace malloc_count {
inline std::atomic<long long> g_live{0};  // bytes held
inline std::atomic<long long> g_peak{0};  // the most held since reset_peak()

inline long long live() { return g_live.load(); }
inline long long peak() { return g_peak.load(); }
inline void reset_peak() { g_peak.store(g_live.load()); }

inline void add(void *p) {
  if (!p) return;
  const long long now = g_live.fetch_add(static_cast<long long>(malloc_usable_size(p))) +
                        static_cast<long long>(malloc_usable_size(p));
  long long seen = g_peak.load();
  while (now > seen && !g_peak.compare_exchange_weak(seen, now)) {
  }
}
inline void remove(void *p) {
  if (p) g_live.fetch_sub(static_cast<long long>(malloc_usable_size(p)));
}
}  // namespace malloc_count

#ifndef SBA_TEST_SANITIZED
extern "C" {
void *__libc_malloc(std::size_t);
void *__libc_calloc(std::size_t, std::size_t);
void *__libc_realloc(void *, std::size_t);
void *__libc_memalign(std::size_t, std::size_t);
void __libc_free(void *);

void *malloc(std::size_t size) {
  void *p = __libc_malloc(size);
  malloc_count::add(p);
  return p;
}
void *calloc(std::size_t count, std::size_t size) {
  void *p = __libc_calloc(count, size);
  malloc_count::add(p);
  return p;
}
void *realloc(void *old, std::size_t size) {
  const long long before = old ? static_cast<long long>(malloc_usable_size(old)) : 0;
  void *p = __libc_realloc(old, size);
  if (p || size == 0) {
    malloc_count::g_live.fetch_sub(before);
    malloc_count::add(p);
  }
  return p;
}
void *memalign(std::size_t align, std::size_t size) {
  void *p = __libc_memalign(align, size);
  malloc_count::add(p);
  return p;
}
void *aligned_alloc(std::size_t align, std::size_t size) { return memalign(align, size); }
int posix_memalign(void **out, std::size_t align, std::size_t size) {
  void *p = memalign(align, size);
  if (!p) return ENOMEM;
  *out = p;
  return 0;
}
void free(void *p) {
  malloc_count::remove(p);
  __libc_free(p);
}
}
#endif

#endif  // SBA_TESTS_COUNTING_MALLOC_H
