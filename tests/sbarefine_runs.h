/* SPDX-License-Identifier: BSD-3-Clause */
// What the tests of sbarefine's formats share (test_colmap.cpp, test_nvm.cpp): scratch
// directories, whole files, a generated scene as eucsbademo files, and runs of sbarefine and
// eucsbademo with the final error they print. The including test defines SBAREFINE_EXE and
// EUCSBADEMO_EXE.
#ifndef SBA_TESTS_SBAREFINE_RUNS_H
#define SBA_TESTS_SBAREFINE_RUNS_H

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "formats/eucsba_io.h"
#include "sbagen.h"

namespace refinetest {

// An empty directory of this process for the test `name`.
inline std::string temp_dir(const std::string &name) {
  const std::string d = testing::TempDir() + "test_refine_" + std::to_string(::getpid()) + "_" + name;
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

inline std::string read_file(const std::string &path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline void write_file(const std::string &path, const std::string &text) {
  std::ofstream(path, std::ios::binary) << text;
}

// Every file and directory under dir, by its path there, with its bytes (a directory: "/"):
// what a failed run must leave as it found it.
using Tree = std::map<std::string, std::string>;
inline Tree tree(const std::string &dir) {
  Tree t;
  for (const auto &e : std::filesystem::recursive_directory_iterator(dir)) {
    const std::string path = std::filesystem::relative(e.path(), dir).string();
    t[path] = e.is_directory() ? "/" : read_file(e.path().string());
  }
  return t;
}

// What differs between two trees, path by path ("+ NEW", "- GONE", "~ CHANGED"); empty when
// nothing does.
inline std::string changes(const Tree &before, const Tree &after) {
  std::string out;
  for (const auto &[path, bytes] : after) {
    const auto was = before.find(path);
    if (was == before.end()) out += "+ " + path + "\n";
    else if (was->second != bytes) out += "~ " + path + "\n";
  }
  for (const auto &entry : before)
    if (after.count(entry.first) == 0) out += "- " + entry.first + "\n";
  return out;
}

// A generated scene (sbagen, seed 5) written as eucsbademo files dir/s-*, and read back, so
// that every format built from it starts from the same doubles as those files.
struct GeneratedScene {
  std::string prefix;
  sbaformats::eucsba::Problem problem;
};

inline GeneratedScene generate_scene(const std::string &dir, sbacameras::euclidean::CameraKind kind, int cameras, int points) {
  sbagen::Options o;
  o.kind = kind;
  o.cameras = cameras;
  o.points = points;
  o.seed = 5;
  sbagen::Scene s;
  std::string error;
  EXPECT_TRUE(sbagen::generate(o, &s, &error)) << error;
  GeneratedScene out;
  out.prefix = dir + "/s";
  EXPECT_TRUE(sbagen::write_problem(s, out.prefix));
  const auto files = sbagen::problem_files(out.prefix, s);
  const sbaformats::eucsba::Status st = sbaformats::eucsba::load_problem(files.cams, files.pts, files.calib, &out.problem);
  EXPECT_TRUE(st) << st.to_string();
  return out;
}

struct Outcome {
  int status = -1;
  std::string out, err;
};

// sbarefine with args (words split by the shell), after the shell text `before` (a pipe
// into it, a ulimit).
inline Outcome run(const std::string &args, const std::string &before = "") {
  const std::string base = testing::TempDir() + "test_refine_run_" + std::to_string(::getpid());
  const std::string command = before + SBAREFINE_EXE + " " + args + " >" + base + ".out 2>" + base + ".err";
  const int st = std::system(command.c_str());
  Outcome r;
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  r.out = read_file(base + ".out");
  r.err = read_file(base + ".err");
  return r;
}

// The final mean squared error of "SBA returned ... error E [initial I]".
inline double final_error(const std::string &out) {
  const std::size_t at = out.find("SBA returned");
  const std::size_t e = out.find(" error ", at);
  if (at == std::string::npos || e == std::string::npos) return NAN;
  return std::strtod(out.c_str() + e + 7, nullptr);
}

// The final error of a program's run (stdout), which must succeed.
inline double program_error(const std::string &command) {
  FILE *p = popen((command + " 2>/dev/null").c_str(), "r");
  std::string out;
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  EXPECT_EQ(pclose(p), 0) << command;
  return final_error(out);
}

inline double eucsbademo_error(const std::string &args) {
  return program_error(std::string(EUCSBADEMO_EXE) + " " + args);
}

}  // namespace refinetest

#endif  // SBA_TESTS_SBAREFINE_RUNS_H
