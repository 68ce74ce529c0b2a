/* SPDX-License-Identifier: BSD-3-Clause */
// What the tests of sbarefine's formats share (test_sbarefine.cpp, test_nvm.cpp): runs of
// sbarefine and eucsbademo with the final error they print, beside the scratch files and
// generated scenes of colmap_fixtures.h. The including test defines SBAREFINE_EXE and
// EUCSBADEMO_EXE.
#ifndef SBA_TESTS_SBAREFINE_RUNS_H
#define SBA_TESTS_SBAREFINE_RUNS_H

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "colmap_fixtures.h"
#include "scratch.h"

namespace refinetest {

struct Outcome {
  int status = -1;
  std::string out, err;
};

// sbarefine with args (words split by the shell), after the shell text `before` (a pipe
// into it, a ulimit).
inline Outcome run(const std::string &args, const std::string &before = "") {
  const std::string base = sbatest::scratch_dir() + "test_refine_run_" + std::to_string(::getpid());
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
