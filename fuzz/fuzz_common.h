/* SPDX-License-Identifier: BSD-3-Clause */
// Shared by the fuzz targets: the eucsbademo readers take paths, so every input is first
// written to a file (in SBA_FUZZ_TMPDIR, which scripts/run_fuzz.sh points at a directory in
// /dev/shm, else /dev/shm or /tmp); and the checks of what the readers promise.
#ifndef SBA_FUZZ_COMMON_H
#define SBA_FUZZ_COMMON_H

#include <unistd.h>

#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace sbafuzz {

// A file of this process for inputs of kind `what`, removed when the process exits normally.
class InputFile {
 public:
  explicit InputFile(const char *what) {
    const char *dir = std::getenv("SBA_FUZZ_TMPDIR");
    if (!dir || !*dir) dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
    path_ = std::string(dir) + "/sba-fuzz-" + std::to_string(getpid()) + "-" + what;
  }
  ~InputFile() { std::remove(path_.c_str()); }
  InputFile(const InputFile &) = delete;
  InputFile &operator=(const InputFile &) = delete;

  const std::string &path() const { return path_; }

  // Replaces the file's content with the input; false if it cannot be written.
  bool write(const std::uint8_t *data, std::size_t size) const {
    std::FILE *f = std::fopen(path_.c_str(), "wb");
    if (!f) return false;
    const bool ok = std::fwrite(data, 1, size, f) == size;
    return std::fclose(f) == 0 && ok;
  }

 private:
  std::string path_;
};

// A broken promise: libFuzzer records the input as a crash.
[[noreturn]] inline void broken(const std::string &what) {
  std::fprintf(stderr, "fuzz: broken promise: %s\n", what.c_str());
  std::abort();
}

inline void require(bool ok, const std::string &what) {
  if (!ok) broken(what);
}

// An error must be one non-empty line that starts with the file's name.
inline void check_error_line(const std::string &msg, const std::string &prefix) {
  require(!msg.empty(), "empty error message");
  require(msg.find('\n') == std::string::npos && msg.find('\r') == std::string::npos,
          "error message of more than one line: " + msg);
  require(msg.compare(0, prefix.size(), prefix) == 0,
          "error message does not start with '" + prefix + "': " + msg);
  require(msg.size() > prefix.size() + 1, "error message without a message: " + msg);
}

// A reader's error about what a file holds, which the file can always be opened here: one line,
// "<path>:<line>: <message>" with the line where it is.
inline void check_format_error(const std::string &msg, const std::string &path) {
  check_error_line(msg, path + ":");
  require(msg.size() > path.size() + 1 && std::isdigit(static_cast<unsigned char>(msg[path.size() + 1])) &&
              msg[path.size() + 1] != '0',
          "a format error without a line number: " + msg);
}

// A text format's reader and writer agree: what parse read from the input (parsed) formats
// to text that parses again and formats to the same text. Returns that text.
template <class T, class Parse, class Format>
std::string require_fixed_point(const T &parsed, Parse parse, Format format, const std::string &name) {
  const std::string once = format(parsed);
  T again;
  std::string error;
  if (!parse(once, name, &again, &error)) broken("the formatted text does not parse: " + error);
  require(format(again) == once, "formatting what was read back gives other text");
  return once;
}

template <class It>
void require_finite(It begin, It end, const std::string &what) {
  for (It it = begin; it != end; ++it) require(std::isfinite(*it), what + " holds a non-finite value");
}

// A normalized quaternion (sbacameras::euclidean::Quaternion or anything with w, x, y, z) of a reader's: of
// unit norm, whatever the size the file gave it.
template <class Q>
void require_rotation(const Q &q, const std::string &what) {
  const double norm = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  require(std::fabs(norm - 1) < 1e-12, what + " does not normalize to a rotation");
}

}  // namespace sbafuzz

#endif
