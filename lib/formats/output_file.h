/* SPDX-License-Identifier: BSD-3-Clause */
// Output of the demo programs: result files that appear whole or not at all, a run's files that
// appear together or not at all, and a check that what they printed on standard output got
// there.
//
// A result file is written under a temporary name beside its final one (FILE.tmp.PID, with a
// counter appended if that name is taken) and renamed onto the final name once it has been
// written and closed without error. A run that fails or is killed midway therefore never leaves
// a truncated file under the final name, and an existing file there stays as it was until the
// new one replaces it. A stale FILE.tmp.* may remain only when the process is killed.
//
// The files of one run (a model, its reports, a COLMAP model's files) form an OutputSet: all
// are written and closed before any is renamed, so that a run that fails leaves no new file, no
// new directory and every existing file (its inputs among them) as it was (see OutputSet).
//
// Paths that are not (or do not lead to) regular files, such as /dev/null, /dev/stdout or a
// FIFO, are written directly: renaming a temporary onto them would replace the device node or
// link instead of writing to it. A symbolic link to a regular file keeps pointing where it
// did: its target is replaced.
#ifndef SBA_LIB_FORMATS_OUTPUT_FILE_H
#define SBA_LIB_FORMATS_OUTPUT_FILE_H

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

namespace sbaformats {

// The folder a file at path is written in (its temporary made there and renamed onto it): the
// folder of path as named, or, for a symbolic link, of the file it leads to.
inline std::string folder_of(const std::string &path) {
  std::string file = path;
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0 && S_ISLNK(st.st_mode))
    if (char *real = ::realpath(path.c_str(), nullptr)) {
      file = real;
      std::free(real);
    }
  const std::size_t slash = file.find_last_of('/');
  if (slash == std::string::npos) return ".";
  return slash == 0 ? "/" : file.substr(0, slash);
}

// Why a file cannot be made in the folder of path, for the errno of a failure that is the
// folder's rather than the file's (no permission, a read-only file system); empty for another.
// A writable file in such a folder cannot be replaced either: its replacement is a new file.
inline std::string folder_refusal(const std::string &path, int err) {
  if (err != EACCES && err != EPERM && err != EROFS) return {};
  return "cannot create files in the folder " + folder_of(path) + ": " + std::strerror(err) +
         " (a file is written under a temporary name beside its own, then renamed)";
}

class OutputFile {
 public:
  OutputFile() = default;
  OutputFile(const OutputFile &) = delete;
  OutputFile &operator=(const OutputFile &) = delete;
  // Not committed: the temporary goes away, the final name is left alone.
  ~OutputFile() { discard(); }

  // Creates the file to write. On failure returns false with the reason (strerror text, e.g.
  // "cannot open for writing: No such file or directory", or folder_refusal's for a folder that
  // takes no new file) in *why.
  bool open(const std::string &path, std::string *why) {
    discard();
    final_ = path;
    replaces_ = false;
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
    // Anything there, a dangling symbolic link included, is not the run's to remove again.
    struct stat there {};
    replaces_ = ::lstat(final_.c_str(), &there) == 0;
    for (int attempt = 0; attempt < 100; ++attempt) {
      std::string temp = final_ + ".tmp." + std::to_string(::getpid());
      if (attempt > 0) temp += "." + std::to_string(attempt);
      // 0666 less the umask, as fopen would create it.
      const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
      if (fd < 0 && errno == EEXIST) continue;
      if (fd < 0) {
        const std::string refusal = folder_refusal(path, errno);
        if (!refusal.empty()) {
          if (why) *why = refusal;
          return false;
        }
      }
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
    created_ = !temp_.empty() && !replaces_;
    temp_.clear();
    return true;
  }

  // Removes the file publish() put where nothing was: false (nothing done) when it replaced a
  // file, or was written in place, since what was there is gone either way.
  bool unpublish() {
    if (!created_) return false;
    created_ = false;
    return std::remove(final_.c_str()) == 0;
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
  bool replaces_ = false;  // something was at final_ when the file was opened
  bool created_ = false;   // publish() made final_, where nothing was
};

// The files of one run, published together: every one is written and closed under its
// temporary first, and commit() renames them all onto their names only once every one is
// written. Until then, and whenever anything fails, the set takes back what it did: it removes
// its temporaries and the directories it made (those left empty), and no existing file has
// changed. A set not committed does the same when it goes.
//
// The renames themselves can fail midway (a rename needs room in the directory, a target may
// have become a directory): what is renamed by then is not all undone, so the order of the
// renames is chosen to keep that window harmless.
// - The files marked publish_last (the model a run writes, which may be its own input: sbarefine
//   MODEL --write MODEL) go after all the others (its reports: --json, the PLY files ...), so a
//   rename that fails among the reports leaves the model, and with it the run's input, as it
//   was. Within each part the files go in the order they were created: a COLMAP model creates
//   its cameras file last, since a reader takes a directory's model by it (colmap_io.cpp).
// - A failed commit removes again the files it had put where nothing was, so that no new file
//   remains; one that replaced an existing file stays replaced (what it replaced is gone).
// - The files to remove (remove_on_commit: the other encoding's model beside a COLMAP model)
//   go after every rename, so that the directory holds a whole model at every moment; a removal
//   that fails is reported with the new files in place.
// Devices and FIFOs are written in place (see OutputFile): what went into them stays there.
class OutputSet {
 public:
  OutputSet() = default;
  OutputSet(const OutputSet &) = delete;
  OutputSet &operator=(const OutputSet &) = delete;
  ~OutputSet() { discard(); }

  // dir as a directory to write into, made when missing (and then removed again, if left
  // empty, unless the set is committed). False with "DIR: why" in *error if it cannot be.
  bool make_directory(const std::string &dir, std::string *error) {
    struct stat st {};
    if (::stat(dir.c_str(), &st) == 0) {
      if (S_ISDIR(st.st_mode)) return true;
      if (error) *error = dir + ": not a directory";
      return false;
    }
    if (::mkdir(dir.c_str(), 0777) != 0) {
      if (error) *error = dir + ": cannot create the directory: " + std::strerror(errno);
      return false;
    }
    made_.push_back(dir);
    return true;
  }

  // A new file of the set, open for writing under its temporary: null, with the reason (as
  // OutputFile::open gives it) in *why, when it cannot be created.
  OutputFile *create(const std::string &path, std::string *why) {
    files_.push_back({std::make_unique<OutputFile>(), path, false});
    if (files_.back().file->open(path, why)) return files_.back().file.get();
    files_.pop_back();
    return nullptr;
  }
  // Ends the writing of a file create() returned: false, with the reason in *why and the file
  // no longer part of the set, on a write or close error.
  bool close(OutputFile *file, std::string *why) {
    if (file->close(why)) return true;
    drop(file);
    return false;
  }
  // Takes a file create() returned out of the set, its temporary removed: a writer that gives
  // up on it.
  void drop(OutputFile *file) {
    for (std::size_t k = 0; k < files_.size(); ++k)
      if (files_[k].file.get() == file) {
        files_.erase(files_.begin() + static_cast<std::ptrdiff_t>(k));
        return;
      }
  }

  // Calls write(), which creates files in this set (the run's model), and marks the files it
  // created to be renamed after every other file of the set, whatever is created later (see
  // above). Returns what write() returns.
  template <class Write>
  bool publish_last(Write write) {
    const std::size_t first = files_.size();
    if (!write()) return false;
    for (std::size_t k = first; k < files_.size(); ++k) files_[k].last = true;
    return true;
  }

  // A file commit() removes: `what` it is ("PATH: cannot remove WHAT: why" when that fails),
  // and `why` it goes, for the program to say (removed()).
  struct Removal {
    std::string path, what, why;
  };

  // path is removed once every file of the set is in place (a missing one is no error).
  void remove_on_commit(const std::string &path, const std::string &what, const std::string &why) {
    removals_.push_back({path, what, why});
  }
  // The files the last commit removed (those of remove_on_commit that were there), in order.
  const std::vector<Removal> &removed() const { return removed_; }

  // Renames every file onto its name (devices and FIFOs: already written), then removes the
  // files remove_on_commit named. False with "PATH: why" in *error on the first failure; the
  // set then takes back what it can (see above).
  bool commit(std::string *error) {
    std::string why;
    for (Entry &e : files_)
      if (e.file->get() && !e.file->close(&why)) return failed(e.path, why, error);
    for (const bool last : {false, true})
      for (Entry &e : files_)
        if (e.last == last && !e.file->publish(&why)) return failed(e.path, why, error);
    files_.clear();
    made_.clear();
    removed_.clear();
    for (const Removal &r : removals_) {
      if (std::remove(r.path.c_str()) == 0) {
        removed_.push_back(r);
      } else if (errno != ENOENT) {
        why = std::strerror(errno);
        removals_.clear();
        return failed(r.path, "cannot remove " + r.what + ": " + why, error);
      }
    }
    removals_.clear();
    return true;
  }

  // Takes back everything: the temporaries, the files a failed commit published where nothing
  // was, the directories made (those that are empty).
  void discard() {
    for (Entry &e : files_) e.file->unpublish();
    files_.clear();  // each OutputFile removes its temporary
    for (auto dir = made_.rbegin(); dir != made_.rend(); ++dir) ::rmdir(dir->c_str());
    made_.clear();
    removals_.clear();
  }

 private:
  struct Entry {
    std::unique_ptr<OutputFile> file;  // where the file's temporary is known; not movable
    std::string path;                  // as the caller named it, for messages
    bool last;
  };
  bool failed(const std::string &path, const std::string &why, std::string *error) {
    if (error) *error = path + ": " + why;
    discard();
    return false;
  }

  std::vector<Entry> files_;
  std::vector<std::string> made_;  // directories made, in order
  std::vector<Removal> removals_;
  std::vector<Removal> removed_;
};

// The file a writer streams into: in *set (renamed when the set is committed) or, set null, a
// file of its own, renamed when close() succeeds. Reasons as OutputFile gives them.
class SetFile {
 public:
  explicit SetFile(OutputSet *set) : set_(set) {}
  SetFile(const SetFile &) = delete;
  SetFile &operator=(const SetFile &) = delete;
  // A file left unclosed (its writer failed) is not part of the set.
  ~SetFile() {
    if (set_ && file_ && file_->get()) set_->drop(file_);
  }
  bool open(const std::string &path, std::string *why) {
    file_ = set_ ? set_->create(path, why) : own_.open(path, why) ? &own_ : nullptr;
    return file_ != nullptr;
  }
  std::FILE *get() const { return file_->get(); }
  bool close(std::string *why) {
    if (!set_) return own_.commit(why);
    OutputFile *file = file_;
    file_ = nullptr;  // the set's from here on, or gone
    return set_->close(file, why);
  }

 private:
  OutputSet *set_;
  OutputFile own_;
  OutputFile *file_ = nullptr;
};

// Writes text as the whole file path: into *set, or (set null) renamed onto path at once. False
// with "PATH: why" in *error if it cannot.
inline bool write_whole_file(const std::string &path, const std::string &text, std::string *error,
                             OutputSet *set = nullptr) {
  SetFile file(set);
  std::string why;
  if (file.open(path, &why)) {
    std::fwrite(text.data(), 1, text.size(), file.get());
    if (file.close(&why)) return true;
  }
  if (error) *error = path + ": " + why;
  return false;
}

// Checks before a long computation that path can be written, without changing an existing
// file and without leaving a new one behind: false with the reason in *why if not. Devices
// and FIFOs pass unopened: opening a FIFO could block, or end the stream its reader waits on.
// The folder must take a new file (the temporary a file is written under), even when the file
// itself is writable.
inline bool probe_writable(const std::string &path, std::string *why) {
  struct stat st {};
  const bool existed = ::stat(path.c_str(), &st) == 0;
  if (existed && S_ISDIR(st.st_mode)) {
    if (why) *why = std::string("cannot open for writing: ") + std::strerror(EISDIR);
    return false;
  }
  if (existed && !S_ISREG(st.st_mode)) return true;
  if (::faccessat(AT_FDCWD, folder_of(path).c_str(), W_OK | X_OK, AT_EACCESS) != 0) {
    const std::string refusal = folder_refusal(path, errno);
    if (!refusal.empty()) {
      if (why) *why = refusal;
      return false;
    }
  }
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
// whose report was lost (a full disk, a closed stdout) must not exit as a success. Call it where
// the output ends (before publish_outputs, and at exit for what follows), without flushing
// stdout before: the flush made here is the one whose errno is known.
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

// The end of a run that wrote files: its outputs are published (OutputSet::commit) once all
// that it printed on standard output got there, so that a run that fails at the last moment
// still leaves its inputs as they were. False when either fails, said on stderr
// ("PATH: why" for a file).
inline bool publish_outputs(const char *program, OutputSet *outputs) {
  if (!stdout_written(program)) return false;
  std::string error;
  if (outputs->commit(&error)) return true;
  std::fprintf(stderr, "%s\n", error.c_str());
  return false;
}

}  // namespace sbaformats

#endif  // SBA_LIB_FORMATS_OUTPUT_FILE_H
