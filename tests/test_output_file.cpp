// SPDX-License-Identifier: BSD-3-Clause
// The files of a run (lib/formats/output_file.h): a write error said as it is, and a set of
// files that is put in place whole or not at all.
#include <gtest/gtest.h>

#include <grp.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "colmap_fixtures.h"
#include "formats/output_file.h"

namespace {

using namespace refinetest;  // NOLINT: the helpers of the format tests

// The full disk of the write error tests: /dev/full fails every write with ENOSPC, and the
// message says so (the errno of the failed write, not of what came after it).
TEST(OutputFile, FullDiskIsSaidAsSuch) {
  if (::access("/dev/full", W_OK) != 0) GTEST_SKIP() << "no /dev/full";
  std::string error;
  EXPECT_FALSE(sbaformats::write_whole_file("/dev/full", std::string(1 << 16, 'x'), &error));
  EXPECT_EQ(error, "/dev/full: write failed: No space left on device");
  EXPECT_FALSE(sbaformats::write_whole_file("/dev/full", "x", &error));
  EXPECT_EQ(error, "/dev/full: write failed: No space left on device");
}

// What probe_writable and OutputFile::open say of a writable file, a new file and a file seen
// through a symbolic link, all in a folder that takes no new file, as a user other than root
// sees them (a child process that is nobody when the test runs as root); empty when no such
// user can be had.
std::vector<std::string> refusals_in(const std::string &folder) {
  int fds[2];
  if (::pipe(fds) != 0) return {};
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(fds[0]);
    if (::geteuid() == 0 && (::setgroups(0, nullptr) != 0 || ::setgid(65534) != 0 || ::setuid(65534) != 0))
      ::_exit(1);
    std::string said;
    for (const char *file : {"/a.txt", "/new.txt", "/../link.txt"}) {
      std::string why;
      said += (sbaformats::probe_writable(folder + file, &why) ? "writable" : why) + "\n";
      sbaformats::OutputFile f;
      why.clear();
      said += (f.open(folder + file, &why) ? "opened" : why) + "\n";
    }
    const ssize_t n = ::write(fds[1], said.data(), said.size());
    ::_exit(n == static_cast<ssize_t>(said.size()) ? 0 : 1);
  }
  ::close(fds[1]);
  std::string said;
  char buf[4096];
  for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) > 0;) said.append(buf, static_cast<std::size_t>(n));
  ::close(fds[0]);
  int status = 0;
  ::waitpid(child, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) return {};
  std::vector<std::string> lines;
  for (std::size_t at = 0, eol; (eol = said.find('\n', at)) != std::string::npos; at = eol + 1)
    lines.push_back(said.substr(at, eol - at));
  return lines;
}

// A file in a folder that takes no new file cannot be replaced, however writable it is: its
// replacement is a new file of that folder, renamed onto it. The message names the folder,
// before a long computation (probe_writable) as when the file is made (OutputFile::open); for
// a symbolic link, the folder of the file it leads to.
TEST(OutputFile, AFolderThatTakesNoNewFileIsNamed) {
  const std::string dir = temp_dir("read_only_folder");
  const std::string folder = dir + "/ro";
  std::filesystem::create_directories(folder);
  write_file(folder + "/a.txt", "OLD\n");
  ASSERT_EQ(::chmod((folder + "/a.txt").c_str(), 0666), 0);
  ASSERT_EQ(::symlink("ro/a.txt", (dir + "/link.txt").c_str()), 0);
  ASSERT_EQ(::chmod(folder.c_str(), 0555), 0);
  const std::vector<std::string> said = refusals_in(folder);
  ASSERT_EQ(::chmod(folder.c_str(), 0755), 0);
  if (said.empty()) GTEST_SKIP() << "no user without the permission to write everywhere";
  const std::string refusal = "cannot create files in the folder " + folder +
                              ": Permission denied (a file is written under a temporary name beside its own, "
                              "then renamed)";
  const std::string through_link = "cannot create files in the folder " +
                                   std::filesystem::canonical(folder).string() +
                                   ": Permission denied (a file is written under a temporary name beside its own, "
                                   "then renamed)";
  EXPECT_EQ(said, (std::vector<std::string>{refusal, refusal, refusal, refusal, through_link, through_link}));
  EXPECT_EQ(read_file(folder + "/a.txt"), "OLD\n");
  EXPECT_EQ(entries(folder), std::vector<std::string>{"a.txt"});
}

// The files of a run go together (output_file.h): a set whose commit fails at a rename among
// its reports removes the reports it had put in place and the directory it made, and leaves
// the model, renamed last, as it was. A target that has become a directory fails the rename,
// root or not.
TEST(OutputSet, FailedRenameTakesBackTheNewFilesAndLeavesTheModel) {
  namespace fs = std::filesystem;
  const std::string dir = temp_dir("output_set");
  const std::string model = dir + "/model.txt";
  write_file(model, "OLD\n");
  // The model (renamed last), a report in a directory the set makes, another report.
  const auto fill = [&](sbaformats::OutputSet *set) {
    std::string error;
    ASSERT_TRUE(set->make_directory(dir + "/new", &error)) << error;
    const bool model_written =
        set->publish_last([&] { return sbaformats::write_whole_file(model, "NEW\n", &error, set); });
    ASSERT_TRUE(model_written) << error;
    ASSERT_TRUE(sbaformats::write_whole_file(dir + "/new/report.json", "{}\n", &error, set)) << error;
    ASSERT_TRUE(sbaformats::write_whole_file(dir + "/r.ply", "ply\n", &error, set)) << error;
    EXPECT_EQ(read_file(model), "OLD\n");  // nothing in place before the commit
    EXPECT_FALSE(fs::exists(dir + "/new/report.json"));
  };
  {
    sbaformats::OutputSet set;
    fill(&set);
    fs::create_directories(dir + "/r.ply/in");
    std::string error;
    EXPECT_FALSE(set.commit(&error));
    EXPECT_EQ(error, dir + "/r.ply: cannot replace the file: Is a directory");
  }
  fs::remove_all(dir + "/r.ply");
  EXPECT_EQ(entries(dir), std::vector<std::string>{"model.txt"});
  EXPECT_EQ(read_file(model), "OLD\n");
  {
    sbaformats::OutputSet set;  // not committed
    fill(&set);
  }
  EXPECT_EQ(entries(dir), std::vector<std::string>{"model.txt"});
  EXPECT_EQ(read_file(model), "OLD\n");
  sbaformats::OutputSet set;
  fill(&set);
  std::string error;
  ASSERT_TRUE(set.commit(&error)) << error;
  EXPECT_EQ(entries(dir), (std::vector<std::string>{"model.txt", "new", "r.ply"}));
  EXPECT_EQ(read_file(model), "NEW\n");
  EXPECT_EQ(read_file(dir + "/new/report.json"), "{}\n");
}

}  // namespace
