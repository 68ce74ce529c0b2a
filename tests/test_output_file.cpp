// SPDX-License-Identifier: BSD-3-Clause
// The files of a run (lib/formats/output_file.h): a write error said as it is, a file synced
// to the disk before its rename and its folder after it, and a set of files that is put in
// place whole or not at all.
//
// fsync and rename are interposed in this test's binary only (-Wl,--wrap=fsync,--wrap=rename,
// tests/CMakeLists.txt): every call is recorded while a test asks, and an fsync can be made
// to fail.
#include <gtest/gtest.h>

#include <grp.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "colmap_fixtures.h"
#include "formats/output_file.h"

namespace interposed {
bool recording = false;
std::vector<std::string> calls;  // "fsync PATH" (the descriptor's file), "rename FROM TO"
int fail_fsync = 0;              // fsync calls to let through before the one that fails
int fail_errno = 0;              // its errno; 0: none fails
}  // namespace interposed

extern "C" {
int __real_fsync(int fd);
int __real_rename(const char *from, const char *to);

int __wrap_fsync(int fd) {
  if (interposed::recording) {
    char path[4096];
    const ssize_t n = ::readlink(("/proc/self/fd/" + std::to_string(fd)).c_str(), path, sizeof path - 1);
    interposed::calls.push_back("fsync " + std::string(path, n > 0 ? static_cast<std::size_t>(n) : 0));
  }
  if (interposed::fail_errno != 0 && interposed::fail_fsync-- == 0) {
    errno = interposed::fail_errno;
    interposed::fail_errno = 0;
    return -1;
  }
  return __real_fsync(fd);
}

int __wrap_rename(const char *from, const char *to) {
  if (interposed::recording) interposed::calls.push_back(std::string("rename ") + from + " " + to);
  return __real_rename(from, to);
}
}

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

// Records the calls of fsync and rename while it lives; with an errno, the (skip + 1)th fsync
// from now fails with it.
class Interposed {
 public:
  explicit Interposed(int fail_errno = 0, int skip = 0) {
    interposed::calls.clear();
    interposed::recording = true;
    interposed::fail_errno = fail_errno;
    interposed::fail_fsync = skip;
  }
  ~Interposed() {
    interposed::recording = false;
    interposed::fail_errno = 0;
  }
  const std::vector<std::string> &calls() const { return interposed::calls; }
};

// The file's data reaches the disk before the rename that gives it its name, and the rename
// before the run says it is done: fsync of the temporary, the rename, fsync of the folder, in
// that order, for a file of its own and for each file of a set (all closed, so synced, before
// any is renamed). A file written in place (a device) is neither synced nor renamed.
TEST(OutputFile, SyncedBeforeTheRenameAndTheFolderAfter) {
  const std::string dir = std::filesystem::canonical(temp_dir("synced")).string();
  const std::string pid = std::to_string(::getpid());
  std::string error;
  {
    Interposed io;
    ASSERT_TRUE(sbaformats::write_whole_file(dir + "/a.txt", "A\n", &error)) << error;
    const std::string temp = dir + "/a.txt.tmp." + pid;
    EXPECT_EQ(io.calls(), (std::vector<std::string>{"fsync " + temp, "rename " + temp + " " + dir + "/a.txt",
                                                    "fsync " + dir}));
  }
  EXPECT_EQ(read_file(dir + "/a.txt"), "A\n");
  {
    Interposed io;
    sbaformats::OutputSet set;
    ASSERT_TRUE(sbaformats::write_whole_file(dir + "/b.txt", "B\n", &error, &set)) << error;
    ASSERT_TRUE(sbaformats::write_whole_file(dir + "/a.txt", "A2\n", &error, &set)) << error;
    ASSERT_TRUE(set.commit(&error)) << error;
    const std::string a = dir + "/a.txt", b = dir + "/b.txt";
    EXPECT_EQ(io.calls(), (std::vector<std::string>{"fsync " + b + ".tmp." + pid, "fsync " + a + ".tmp." + pid,
                                                    "rename " + b + ".tmp." + pid + " " + b, "fsync " + dir,
                                                    "rename " + a + ".tmp." + pid + " " + a, "fsync " + dir}));
  }
  EXPECT_EQ(read_file(dir + "/a.txt"), "A2\n");
  EXPECT_EQ(read_file(dir + "/b.txt"), "B\n");
  {
    Interposed io;
    ASSERT_TRUE(sbaformats::write_whole_file("/dev/null", "x", &error)) << error;
    EXPECT_TRUE(io.calls().empty());
  }
}

// A failed sync is a failed write: the file's path and the reason, the temporary removed, the
// final name as it was (absent, or the old file); in a set, no file of the set left. A sync of
// the folder that fails after the rename takes back the file the rename put where nothing was.
TEST(OutputFile, FailedSyncIsAWriteError) {
  const std::string dir = std::filesystem::canonical(temp_dir("sync_fails")).string();
  std::string error;
  write_file(dir + "/old.txt", "OLD\n");
  for (const int err : {EIO, ENOSPC}) {
    SCOPED_TRACE(std::strerror(err));
    for (const char *name : {"/new.txt", "/old.txt"}) {
      Interposed io(err);
      EXPECT_FALSE(sbaformats::write_whole_file(dir + name, "NEW\n", &error));
      EXPECT_EQ(error, dir + name + ": write failed: " + std::strerror(err));
      EXPECT_EQ(io.calls().size(), 1u);  // the failed sync, and neither a rename nor a sync after it
    }
    EXPECT_EQ(entries(dir), std::vector<std::string>{"old.txt"});
    EXPECT_EQ(read_file(dir + "/old.txt"), "OLD\n");
  }
  {
    // The second file of a set fails its sync as its writer closes it; the run gives up.
    Interposed io(EIO, 1);
    sbaformats::OutputSet set;
    ASSERT_TRUE(sbaformats::write_whole_file(dir + "/a.txt", "A\n", &error, &set)) << error;
    EXPECT_FALSE(sbaformats::write_whole_file(dir + "/old.txt", "NEW\n", &error, &set));
    EXPECT_EQ(error, dir + "/old.txt: write failed: Input/output error");
  }
  EXPECT_EQ(entries(dir), std::vector<std::string>{"old.txt"});
  EXPECT_EQ(read_file(dir + "/old.txt"), "OLD\n");
  {
    // The folder's sync after the rename: the new file goes again.
    Interposed io(EIO, 1);
    EXPECT_FALSE(sbaformats::write_whole_file(dir + "/new.txt", "NEW\n", &error));
    EXPECT_EQ(error, dir + "/new.txt: write failed: Input/output error");
    EXPECT_EQ(io.calls().size(), 3u);
  }
  EXPECT_EQ(entries(dir), std::vector<std::string>{"old.txt"});
}

}  // namespace
