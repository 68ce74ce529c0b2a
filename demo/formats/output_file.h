/* SPDX-License-Identifier: BSD-3-Clause */
// Output of the demo programs: result files that appear whole or not at all, and a check that
// what they printed on standard output got there.
//
// A result file is written under a temporary name beside its final one (FILE.tmp.PID, with a
// counter appended if that name is taken) and renamed onto the final name once it has been
// written and closed without error. A run that fails or is killed midway therefore never leaves
// a truncated file under the final name, and an existing file there stays as it was until the
// new one replaces it. A stale FILE.tmp.* may remain only when the process is killed. Files
// that belong together (a COLMAP model's three) are all closed before any is renamed.
//
// Paths that are not (or do not lead to) regular files, such as /dev/null, /dev/stdout or a
// FIFO, are written directly: renaming a temporary onto them would replace the device node or
// link instead of writing to it. A symbolic link to a regular file keeps pointing where it
// did: its target is replaced.
#ifndef SBA_DEMO_OUTPUT_FILE_H
#define SBA_DEMO_OUTPUT_FILE_H

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace sbaformats {

class OutputFile {
 public:
  OutputFile() = default;
  OutputFile(const OutputFile &) = delete;
  OutputFile &operator=(const OutputFile &) = delete;
  // Not committed: the temporary goes away, the final name is left alone.
  ~OutputFile() { discard(); }

  // Creates the file to write. On failure returns false with the reason (strerror text, e.g.
  // "cannot open for writing: No such file or directory") in *why.
  bool open(const std::string &path, std::string *why) {
    discard();
    final_ = path;
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
      // A device, FIFO or directory: written in place (a directory then fails to open).
      return attach(::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666), why);
    }
    // Through a symbolic link: the file it names is the one to replace.
    if (char *real = ::realpath(path.c_str(), nullptr)) {
      final_ = real;
      std::free(real);
    }
    for (int attempt = 0; attempt < 100; ++attempt) {
      std::string temp = final_ + ".tmp." + std::to_string(::getpid());
      if (attempt > 0) temp += "." + std::to_string(attempt);
      // 0666 less the umask, as fopen would create it.
      const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
      if (fd < 0 && errno == EEXIST) continue;
      if (fd >= 0) {
        temp_ = temp;
        // A file being replaced keeps its permission bits.
        if (S_ISREG(st.st_mode)) (void)::fchmod(fd, st.st_mode & 07777);
      }
      return attach(fd, why);
    }
    errno = EEXIST;
    return failed("cannot open for writing: ", why);
  }

  std::FILE *get() const { return file_; }

  // Closes the file and gives it its final name. On a write, close or rename error returns
  // false with the reason in *why; the temporary is then removed and the final name untouched.
  bool commit(std::string *why) { return close(why) && publish(why); }

  // commit() in two steps, for files that appear together: close() ends the writing (false,
  // the temporary removed, on a write or close error), publish() renames the closed file onto
  // its final name. A file closed and not published is removed with its OutputFile.
  bool close(std::string *why) {
    if (!file_) {
      if (why) *why = "write failed: not open";
      return false;
    }
    const bool write_error = std::ferror(file_) != 0;
    const bool closed = std::fclose(file_) == 0;  // flushes through write_fd, closes through close_fd
    file_ = nullptr;
    if (write_error || !closed) {
      const int err = errno_ != 0 ? errno_ : EIO;
      discard();
      errno = err;
      return failed("write failed: ", why);
    }
    return true;
  }
  bool publish(std::string *why) {
    if (!temp_.empty() && std::rename(temp_.c_str(), final_.c_str()) != 0) {
      const int rename_err = errno;
      discard();
      errno = rename_err;
      return failed("cannot replace the file: ", why);
    }
    temp_.clear();
    return true;
  }

  // The temporary's name while one is open (for tests and messages); empty otherwise.
  const std::string &temporary() const { return temp_; }

 private:
  // The stream over fd (which attach owns from here on; -1: open failed, errno says why).
  // It writes through write_fd and close_fd, which keep the errno of the first failure: ferror
  // says only that a write failed, and errno has often moved on by the time anyone asks.
  bool attach(int fd, std::string *why) {
    if (fd < 0) {
      const int err = errno;
      discard();
      errno = err;
      return failed("cannot open for writing: ", why);
    }
    fd_ = fd;
    errno_ = 0;
    file_ = ::fopencookie(this, "w", {nullptr, write_fd, nullptr, close_fd});
    if (!file_) {
      const int err = errno;
      ::close(fd_);
      discard();
      errno = err;
      return failed("cannot open for writing: ", why);
    }
    return true;
  }

  static ssize_t write_fd(void *cookie, const char *buf, std::size_t size) {
    OutputFile *self = static_cast<OutputFile *>(cookie);
    std::size_t done = 0;
    while (done < size) {
      const ssize_t n = ::write(self->fd_, buf + done, size - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        if (self->errno_ == 0) self->errno_ = n < 0 ? errno : EIO;
        break;
      }
      done += static_cast<std::size_t>(n);
    }
    return static_cast<ssize_t>(done);  // short: the stream's error flag is set
  }
  static int close_fd(void *cookie) {
    OutputFile *self = static_cast<OutputFile *>(cookie);
    const int rc = ::close(self->fd_);
    if (rc != 0 && self->errno_ == 0) self->errno_ = errno;
    return rc;
  }

  void discard() {
    if (file_) std::fclose(file_);
    file_ = nullptr;
    if (!temp_.empty()) std::remove(temp_.c_str());
    temp_.clear();
  }

  bool failed(const char *what, std::string *why) const {
    if (why) *why = std::string(what) + std::strerror(errno);
    return false;
  }

  std::FILE *file_ = nullptr;
  int fd_ = -1;        // under file_
  int errno_ = 0;      // the first write or close error of file_
  std::string final_;  // where the file ends up
  std::string temp_;   // the temporary, empty when writing in place or when none is open
};

// Writes text as the whole file path through *file and closes it, not yet published: false
// with "PATH: why" in *error if it cannot.
inline bool write_closed(const std::string &path, const std::string &text, OutputFile *file, std::string *error) {
  std::string why;
  if (file->open(path, &why)) {
    std::fwrite(text.data(), 1, text.size(), file->get());
    if (file->close(&why)) return true;
  }
  if (error) *error = path + ": " + why;
  return false;
}

// Writes text as the whole file path (through OutputFile): false with "PATH: why" in *error
// if it cannot.
inline bool write_whole_file(const std::string &path, const std::string &text, std::string *error) {
  OutputFile file;
  std::string why;
  if (!write_closed(path, text, &file, error)) return false;
  if (file.publish(&why)) return true;
  if (error) *error = path + ": " + why;
  return false;
}

// Checks before a long computation that path can be written, without changing an existing
// file and without leaving a new one behind: false with the reason in *why if not. Devices
// and FIFOs pass unopened: opening a FIFO could block, or end the stream its reader waits on.
inline bool probe_writable(const std::string &path, std::string *why) {
  struct stat st {};
  const bool existed = ::stat(path.c_str(), &st) == 0;
  if (existed && S_ISDIR(st.st_mode)) {
    if (why) *why = std::string("cannot open for writing: ") + std::strerror(EISDIR);
    return false;
  }
  if (existed && !S_ISREG(st.st_mode)) return true;
  std::FILE *probe = std::fopen(path.c_str(), "a");
  if (!probe) {
    if (why) *why = std::string("cannot open for writing: ") + std::strerror(errno);
    return false;
  }
  std::fclose(probe);
  if (!existed) std::remove(path.c_str());
  return true;
}

// Flushes standard output and reports whether everything printed on it was written; if not,
// prints "PROGRAM: error writing standard output: REASON" on stderr and returns false. A run
// whose report was lost (a full disk, a closed stdout) must not exit as a success. Call it once,
// at the end, without flushing stdout before: the final flush is the one whose errno is known.
inline bool stdout_written(const char *program) {
  errno = 0;
  const bool flushed = std::fflush(stdout) == 0;
  const int err = errno;
  if (flushed && !std::ferror(stdout)) return true;
  // When an earlier implicit flush failed, its errno is gone: say what is known.
  if (err != 0) std::fprintf(stderr, "%s: error writing standard output: %s\n", program, std::strerror(err));
  else std::fprintf(stderr, "%s: error writing standard output\n", program);
  return false;
}

}  // namespace sbaformats

#endif  // SBA_DEMO_OUTPUT_FILE_H
