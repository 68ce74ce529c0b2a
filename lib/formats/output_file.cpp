// SPDX-License-Identifier: BSD-3-Clause
#include "formats/output_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

namespace sbaformats {
namespace {

// The stream's writes and close, through the descriptor (fopencookie), keeping the errno of
// the first failure.
ssize_t write_fd(void *cookie, const char *buf, std::size_t size) {
  OutputFile::Descriptor *io = static_cast<OutputFile::Descriptor *>(cookie);
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(io->fd, buf + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      if (io->error == 0) io->error = n < 0 ? errno : EIO;
      break;
    }
    done += static_cast<std::size_t>(n);
  }
  return static_cast<ssize_t>(done);  // short: the stream's error flag is set
}

int close_fd(void *cookie) {
  OutputFile::Descriptor *io = static_cast<OutputFile::Descriptor *>(cookie);
  const int rc = ::close(io->fd);
  if (rc != 0 && io->error == 0) io->error = errno;
  return rc;
}

// Syncs the folder of a file just renamed into it, so that the rename outlives a power loss;
// 0, or the errno of the failure. A folder that cannot be opened for reading (permission to
// write and search only) cannot be synced by this process, and some file systems sync no
// folder (EINVAL): neither is a failure of the write, and the file is whole either way.
int sync_folder(const std::string &file) {
  const int fd = ::open(folder_of(file).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return 0;
  int err = ::fsync(fd) == 0 ? 0 : errno;
  ::close(fd);
  if (err == EINVAL || err == ENOTSUP || err == EOPNOTSUPP) err = 0;
  return err;
}

bool failed(const char *what, std::string *why) {
  if (why) *why = std::string(what) + std::strerror(errno);
  return false;
}

}  // namespace

std::string folder_of(const std::string &path) {
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

std::string folder_refusal(const std::string &path, int err) {
  if (err != EACCES && err != EPERM && err != EROFS) return {};
  return "cannot create files in the folder " + folder_of(path) + ": " + std::strerror(err) +
         " (a file is written under a temporary name beside its own, then renamed)";
}

// ---- OutputFile ----

bool OutputFile::open(const std::string &path, std::string *why) {
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

bool OutputFile::commit(std::string *why) {
  if (!close(why)) return false;
  if (publish(why)) return true;
  unpublish();
  return false;
}

bool OutputFile::close(std::string *why) {
  if (!file_) {
    if (why) *why = "write failed: not open";
    return false;
  }
  // A file to be renamed reaches the disk before the rename does (see the top of the header).
  // A file written in place is a device or a FIFO, which nothing renames and most cannot sync.
  bool synced = true;
  if (!temp_.empty() && std::fflush(file_) == 0 && ::fsync(io_.fd) != 0) {
    synced = false;
    if (io_.error == 0) io_.error = errno;
  }
  const bool write_error = std::ferror(file_) != 0;
  const bool closed = std::fclose(file_) == 0;  // flushes through write_fd, closes through close_fd
  file_ = nullptr;
  if (write_error || !closed || !synced) {
    const int err = io_.error != 0 ? io_.error : EIO;
    discard();
    errno = err;
    return failed("write failed: ", why);
  }
  return true;
}

bool OutputFile::publish(std::string *why) {
  if (temp_.empty()) {
    created_ = false;
    return true;
  }
  if (std::rename(temp_.c_str(), final_.c_str()) != 0) {
    const int rename_err = errno;
    discard();
    errno = rename_err;
    return failed("cannot replace the file: ", why);
  }
  created_ = !replaces_;
  temp_.clear();
  if (const int err = sync_folder(final_)) {
    errno = err;
    return failed("write failed: ", why);
  }
  return true;
}

bool OutputFile::unpublish() {
  if (!created_) return false;
  created_ = false;
  return std::remove(final_.c_str()) == 0;
}

// The stream over fd (which attach owns from here on; -1: open failed, errno says why).
bool OutputFile::attach(int fd, std::string *why) {
  if (fd < 0) {
    const int err = errno;
    discard();
    errno = err;
    return failed("cannot open for writing: ", why);
  }
  io_ = {fd, 0};
  file_ = ::fopencookie(&io_, "w", {nullptr, write_fd, nullptr, close_fd});
  if (!file_) {
    const int err = errno;
    ::close(fd);
    discard();
    errno = err;
    return failed("cannot open for writing: ", why);
  }
  return true;
}

void OutputFile::discard() {
  if (file_) std::fclose(file_);
  file_ = nullptr;
  if (!temp_.empty()) std::remove(temp_.c_str());
  temp_.clear();
}

// ---- OutputSet ----

bool OutputSet::make_directory(const std::string &dir, std::string *error) {
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

OutputFile *OutputSet::create(const std::string &path, std::string *why) {
  files_.push_back({std::make_unique<OutputFile>(), path, false});
  if (files_.back().file->open(path, why)) return files_.back().file.get();
  files_.pop_back();
  return nullptr;
}

bool OutputSet::close(OutputFile *file, std::string *why) {
  if (file->close(why)) return true;
  drop(file);
  return false;
}

void OutputSet::drop(OutputFile *file) {
  for (std::size_t k = 0; k < files_.size(); ++k)
    if (files_[k].file.get() == file) {
      files_.erase(files_.begin() + static_cast<std::ptrdiff_t>(k));
      return;
    }
}

bool OutputSet::commit(std::string *error) {
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

void OutputSet::discard() {
  for (Entry &e : files_) e.file->unpublish();
  files_.clear();  // each OutputFile removes its temporary
  for (auto dir = made_.rbegin(); dir != made_.rend(); ++dir) ::rmdir(dir->c_str());
  made_.clear();
  removals_.clear();
}

bool OutputSet::failed(const std::string &path, const std::string &why, std::string *error) {
  if (error) *error = path + ": " + why;
  discard();
  return false;
}

// ---- SetFile and the helpers ----

SetFile::~SetFile() {
  if (set_ && file_ && file_->get()) set_->drop(file_);
}

bool SetFile::open(const std::string &path, std::string *why) {
  file_ = set_ ? set_->create(path, why) : own_.open(path, why) ? &own_ : nullptr;
  return file_ != nullptr;
}

bool SetFile::close(std::string *why) {
  if (!set_) return own_.commit(why);
  OutputFile *file = file_;
  file_ = nullptr;  // the set's from here on, or gone
  return set_->close(file, why);
}

bool write_whole_file(const std::string &path, const std::string &text, std::string *error, OutputSet *set) {
  SetFile file(set);
  std::string why;
  if (file.open(path, &why)) {
    std::fwrite(text.data(), 1, text.size(), file.get());
    if (file.close(&why)) return true;
  }
  if (error) *error = path + ": " + why;
  return false;
}

bool probe_writable(const std::string &path, std::string *why) {
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

bool stdout_written(const char *program) {
  errno = 0;
  const bool flushed = std::fflush(stdout) == 0;
  const int err = errno;
  if (flushed && !std::ferror(stdout)) return true;
  // When an earlier implicit flush failed, its errno is gone: say what is known.
  if (err != 0) std::fprintf(stderr, "%s: error writing standard output: %s\n", program, std::strerror(err));
  else std::fprintf(stderr, "%s: error writing standard output\n", program);
  return false;
}

bool publish_outputs(const char *program, OutputSet *outputs) {
  if (!stdout_written(program)) return false;
  std::string error;
  if (outputs->commit(&error)) return true;
  std::fprintf(stderr, "%s\n", error.c_str());
  return false;
}

}  // namespace sbaformats
