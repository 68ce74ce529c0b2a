/* SPDX-License-Identifier: BSD-3-Clause */
// Where a test process keeps the files it writes: one directory per process under gtest's
// TempDir(), removed with everything in it when the process exits, so that a test run leaves
// nothing behind in /tmp. SBA_KEEP_TEST_FILES=1 keeps it, to look at what a failing test wrote.
// A child forked by a death test or a fault test exits through the same static destructors:
// only the process that made the directory removes it.
#ifndef SBA_TESTS_SCRATCH_H
#define SBA_TESTS_SCRATCH_H

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>

namespace sbatest {

// Removes its directory when destroyed in the process that made it.
class ScratchRoot {
 public:
  explicit ScratchRoot(std::string path) : path_(std::move(path)), owner_(::getpid()) {
    std::filesystem::create_directories(path_);
  }
  ~ScratchRoot() {
    const char *keep = std::getenv("SBA_KEEP_TEST_FILES");
    if (::getpid() != owner_ || (keep && *keep && std::string(keep) != "0")) return;
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchRoot(const ScratchRoot &) = delete;
  ScratchRoot &operator=(const ScratchRoot &) = delete;
  const std::string &path() const { return path_; }

 private:
  std::string path_;
  pid_t owner_;
};

// This process's scratch directory, with a trailing '/' (as testing::TempDir()'s).
inline const std::string &scratch_dir() {
  static const ScratchRoot root(testing::TempDir() + "sba-tests." + std::to_string(::getpid()) + "/");
  return root.path();
}

}  // namespace sbatest

#endif
