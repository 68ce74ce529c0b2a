// SPDX-License-Identifier: BSD-3-Clause
#include "log.h"

#include <cstdarg>
#include <cstdio>
#include <cstring>

namespace sba {

void Logger::emit(LogLevel level, const char *fmt, va_list ap) const {
  char line[1024];
  std::vsnprintf(line, sizeof line, fmt, ap);
  if (sink_) {
    sink_(ctx_, static_cast<int>(level), line);
    return;
  }
  // 1.6 printed progress on stdout and problems on stderr; programs parse both.
  std::FILE *out = level == LogLevel::Info ? stdout : stderr;
  std::fprintf(out, "%s\n", line);
  std::fflush(out);
}

void Logger::error(const char *fmt, ...) const {
  va_list ap;
  va_start(ap, fmt);
  emit(LogLevel::Error, fmt, ap);
  va_end(ap);
}

void Logger::warning(const char *fmt, ...) const {
  if (verbose_ < 1) return;
  va_list ap;
  va_start(ap, fmt);
  emit(LogLevel::Warning, fmt, ap);
  va_end(ap);
}

void Logger::notice(const char *fmt, ...) const {
  va_list ap;
  va_start(ap, fmt);
  emit(LogLevel::Warning, fmt, ap);
  va_end(ap);
}

void Logger::legacy(int level, const char *fmt, ...) const {
  if (verbose_ < level) return;
  char text[1024];
  va_list ap;
  va_start(ap, fmt);
  std::vsnprintf(text, sizeof text, fmt, ap);
  va_end(ap);
  if (!sink_) {
    std::fputs(text, stdout);
    std::fflush(stdout);
    return;
  }
  // One sink call per line; a text ending in a newline has no empty line after it.
  for (char *line = text; *line;) {
    char *end = std::strchr(line, '\n');
    if (end) *end = '\0';
    sink_(ctx_, static_cast<int>(LogLevel::Info), line);
    if (!end) break;
    line = end + 1;
  }
}

void Logger::info(int level, const char *fmt, ...) const {
  if (!sink_ || verbose_ < level) return;
  va_list ap;
  va_start(ap, fmt);
  emit(LogLevel::Info, fmt, ap);
  va_end(ap);
}

void Logger::report(const char *fmt, ...) const {
  va_list ap;
  va_start(ap, fmt);
  emit(LogLevel::Warning, fmt, ap);
  va_end(ap);
}

}  // namespace sba
