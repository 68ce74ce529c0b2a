/* SPDX-License-Identifier: BSD-3-Clause */
// SBA_TEST_SANITIZED is defined when the tests (and so the library and programs, which are
// built the same way) run under AddressSanitizer or ThreadSanitizer: they replace operator new
// and reserve terabytes of address space for their shadow memory, so a counting operator new
// or an address-space limit (RLIMIT_AS) cannot work there; the sanitizers check leaks
// themselves.
#ifndef SBA_TESTS_SANITIZED_H
#define SBA_TESTS_SANITIZED_H

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define SBA_TEST_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define SBA_TEST_SANITIZED 1
#endif
#endif

#endif
