// SPDX-License-Identifier: BSD-3-Clause
// The files of a run (lib/formats/output_file.h): a write error said as it is, and a set of
// files that is put in place whole or not at all.
#include <gtest/gtest.h>

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
