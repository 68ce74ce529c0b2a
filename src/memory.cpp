// SPDX-License-Identifier: BSD-3-Clause
#include "memory.h"

#include <cstdint>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

namespace sba {

void prefault(void *p, std::size_t bytes) {
#if defined(__linux__)
#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23  // the kernel's value; older C libraries do not name it
#endif
  const long page = sysconf(_SC_PAGESIZE);
  if (page <= 0) return;
  const auto pg = std::uintptr_t(page), a = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t b = (a + pg - 1) / pg * pg, e = (a + bytes) / pg * pg;
  // The partial pages at either end are mapped when they are zeroed. A kernel without
  // MADV_POPULATE_WRITE answers EINVAL, and one short of memory ENOMEM: either way the
  // pages are left to be mapped on first touch, as without this call.
  if (e > b) (void)madvise(reinterpret_cast<void *>(b), e - b, MADV_POPULATE_WRITE);
#else
  (void)p;
  (void)bytes;
#endif
}

namespace {

template <class T>
void resize_prefaulted_t(std::vector<T> &v, std::size_t n) {
  // Below a few pages the allocation most likely comes from memory the process has
  // already touched, and the system call would cost more than it saves.
  constexpr std::size_t kMinBytes = 64 * 1024;
  if (n * sizeof(T) >= kMinBytes && v.capacity() < n) {
    v.reserve(n);
    prefault(v.data(), n * sizeof(T));
  }
  v.resize(n);
}

}  // namespace

void resize_prefaulted(std::vector<double> &v, std::size_t n) { resize_prefaulted_t(v, n); }
void resize_prefaulted(std::vector<float> &v, std::size_t n) { resize_prefaulted_t(v, n); }

}  // namespace sba
