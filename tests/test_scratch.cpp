// SPDX-License-Identifier: BSD-3-Clause
// scratch.h: the directory a test process writes into goes when the process does.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include "scratch.h"

namespace {

namespace fs = std::filesystem;

std::string fresh(const std::string &name) {
  const std::string d = sbatest::scratch_dir() + name;
  fs::remove_all(d);
  return d;
}

TEST(Scratch, DirectoryAndWhatItHoldsAreRemovedWithTheRoot) {
  const std::string d = fresh("root");
  {
    const sbatest::ScratchRoot root(d + "/");
    ASSERT_TRUE(fs::is_directory(d));
    fs::create_directories(d + "/a/b");
    std::ofstream(d + "/a/b/f.txt") << "x";
  }
  EXPECT_FALSE(fs::exists(d));
}

TEST(Scratch, KeptWhenAsked) {
  const std::string d = fresh("kept");
  ASSERT_EQ(setenv("SBA_KEEP_TEST_FILES", "1", 1), 0);
  { const sbatest::ScratchRoot root(d + "/"); }
  unsetenv("SBA_KEEP_TEST_FILES");
  EXPECT_TRUE(fs::is_directory(d));
  ASSERT_EQ(setenv("SBA_KEEP_TEST_FILES", "0", 1), 0);
  { const sbatest::ScratchRoot root(d + "/"); }
  unsetenv("SBA_KEEP_TEST_FILES");
  EXPECT_FALSE(fs::exists(d));
}

// A forked child that ends through the static destructors (exit, not _exit) leaves the
// parent's directory alone.
TEST(Scratch, AForkedChildDoesNotRemoveItsParentsDirectory) {
  const std::string d = fresh("forked");
  auto root = std::make_unique<sbatest::ScratchRoot>(d + "/");
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    root.reset();
    std::exit(0);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  EXPECT_TRUE(fs::is_directory(d));
  root.reset();
  EXPECT_FALSE(fs::exists(d));
}

TEST(Scratch, OneDirectoryPerProcessUnderGtestsTempDir) {
  const std::string &s = sbatest::scratch_dir();
  EXPECT_EQ(&s, &sbatest::scratch_dir());
  EXPECT_EQ(s, testing::TempDir() + "sba-tests." + std::to_string(::getpid()) + "/");
  EXPECT_TRUE(fs::is_directory(s));
}

}  // namespace
