/* SPDX-License-Identifier: BSD-3-Clause */
// One logging sink for everything the library says. By default errors go to stderr and
// progress (only when verbose) to stdout, as in sba 1.6; callers of the extension API can
// redirect or silence both.
#ifndef SBA_SRC_LOG_H
#define SBA_SRC_LOG_H

#include <cstdarg>
#include <exception>
#include <new>

#include "forced_unwind.h"

namespace sba {

enum class LogLevel { Error = 0, Warning = 1, Info = 2 };

// sink(ctx, level, line): line has no trailing newline.
using LogSinkFn = void (*)(void *ctx, int level, const char *line);

class Logger {
 public:
  Logger() = default;
  Logger(int verbose, LogSinkFn sink, void *ctx) : verbose_(verbose), sink_(sink), ctx_(ctx) {}

  int verbose() const { return verbose_; }

  // Caller errors and failures: always reported (they are the reason for an SBA_ERROR).
  void error(const char *fmt, ...) const __attribute__((format(printf, 2, 3)));
  // Diagnostics that 1.6 printed only sometimes: shown when verbose >= 1.
  void warning(const char *fmt, ...) const __attribute__((format(printf, 2, 3)));
  // A setting the caller made outside the arguments (an environment variable) that is
  // ignored: warning level, shown whatever verbose is, since nothing else would tell.
  void notice(const char *fmt, ...) const __attribute__((format(printf, 2, 3)));
  // sba 1.6's own progress text, in its words, when verbose >= level: on stdout as 1.6 prints
  // it (fmt carries its newlines), or to the sink line by line.
  void legacy(int level, const char *fmt, ...) const __attribute__((format(printf, 3, 4)));
  // The library's own progress lines, beyond 1.6's: only to a caller's sink (a 1.6 caller's
  // stdout gets 1.6's lines and nothing else), when verbose >= level.
  void info(int level, const char *fmt, ...) const __attribute__((format(printf, 3, 4)));
  // A message the caller explicitly asked for (e.g. the Jacobian check with itmax == 0).
  void report(const char *fmt, ...) const __attribute__((format(printf, 2, 3)));

 private:
  void emit(LogLevel level, const char *fmt, va_list ap) const;

  int verbose_ = 0;
  LogSinkFn sink_ = nullptr;
  void *ctx_ = nullptr;
};

// Runs body() and logs whatever it throws as one line naming `who`, since nothing may escape
// a C entry point; false if it threw. Exceptions from the library itself are std::bad_alloc
// or internal errors; anything else came from a caller's callback.
//
// The one thing let through is a forced unwind (glibc and libstdc++: pthread_exit or
// pthread_cancel in a callback, which is how Python ends a daemon thread that takes the GIL
// while the interpreter exits). It is not an error but the end of the calling thread:
// swallowing it makes the runtime abort the process ("exception not rethrown"), and a noexcept
// frame on its way calls std::terminate, which is why neither this function nor the entry
// points that call it are noexcept. Everything the solve holds is freed as it unwinds.
template <class Body>
SBA_CATCHES_FORCED_UNWIND bool catch_all(const Logger &log, const char *who, Body body) {
  try {
    body();
    return true;
  }
#if SBA_HAVE_FORCED_UNWIND
  catch (abi::__forced_unwind &) {
    throw;
  }
#endif
  catch (const std::bad_alloc &) {
    log.error("%s: out of memory", who);
  } catch (const std::exception &e) {
    log.error("%s: internal error: %s", who, e.what());
  } catch (...) {
    log.error("%s: unknown exception from a callback", who);
  }
  return false;
}

}  // namespace sba

#endif
