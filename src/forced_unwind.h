/* SPDX-License-Identifier: BSD-3-Clause */
// A forced unwind: glibc ends a thread (pthread_exit, pthread_cancel; Python ending a daemon
// thread at exit) by unwinding its stack with abi::__forced_unwind, which libstdc++ lets a
// handler catch by that type. It must always be rethrown: a handler that ends without
// rethrowing it makes the runtime abort the process ("FATAL: exception not rethrown").
#ifndef SBA_SRC_FORCED_UNWIND_H
#define SBA_SRC_FORCED_UNWIND_H

#if defined(__GLIBCXX__)
#include <cxxabi.h>
#define SBA_HAVE_FORCED_UNWIND 1
// `catch (abi::__forced_unwind &)` binds a reference to the exception object, which a forced
// unwind does not have: UBSan's null check reports the binding. The functions with such a
// handler are left out of that one check, and never inlined, since the check would follow
// their code into the caller.
#define SBA_CATCHES_FORCED_UNWIND __attribute__((no_sanitize("null"), noinline))
#else
#define SBA_HAVE_FORCED_UNWIND 0
#define SBA_CATCHES_FORCED_UNWIND
#endif

#endif
