// SPDX-License-Identifier: BSD-3-Clause
// The command-line conventions of the four programs (demo/cli/cli.h), checked on the programs
// themselves: the same grammar (--opt=VALUE and --opt VALUE), --help and --version in each,
// and the same one-line message and exit status for the same mistake.
#include <bzlib.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

#include "sanitized.h"
#include "sba.h"
#include "sba_ext.h"
#include "scratch.h"

namespace {

struct Program {
  std::string name, exe;
  std::string int_option;  // an integer option >= 0 (or >= 1) with no upper bound of its own
  std::string int_range;   // what the message says about it
};

std::vector<Program> programs() {
  std::vector<Program> p{{"eucsbademo", EUCSBADEMO_EXE, "itmax", "an integer >= 0"},
                         {"balsba", BALSBA_EXE, "itmax", "an integer >= 0"},
                         {"sbarefine", SBAREFINE_EXE, "itmax", "an integer >= 0"},
                         {"sbagen", SBAGEN_EXE, "points", "an integer >= 1"}};
#ifdef SBA_BENCH_EXE
  p.push_back({"sba_bench", SBA_BENCH_EXE, "itmax", "an integer >= 0"});
#endif
  return p;
}

struct Output {
  int status = -1;
  std::string out, err;
};

std::string slurp(const std::string &path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Runs exe with args (each passed as one word) and captures stdout, stderr and the status;
// standard input from stdin_path.
Output run(const std::string &exe, const std::vector<std::string> &args, const std::string &stdin_path = "/dev/null") {
  const std::string base = sbatest::scratch_dir() + "test_cli." + std::to_string(getpid());
  std::string cmd = "exec '" + exe + "'";
  for (const std::string &a : args) cmd += " '" + a + "'";
  cmd += " >" + base + ".out 2>" + base + ".err <'" + stdin_path + "'";
  Output o;
  const int raw = std::system(cmd.c_str());
  o.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  o.out = slurp(base + ".out");
  o.err = slurp(base + ".err");
  std::remove((base + ".out").c_str());
  std::remove((base + ".err").c_str());
  return o;
}

// One mistake: exit status 2, nothing on stdout, exactly this line on stderr.
void expect_usage_error(const Program &p, const std::vector<std::string> &args, const std::string &message) {
  const Output o = run(p.exe, args);
  EXPECT_EQ(o.status, 2) << p.name;
  EXPECT_EQ(o.out, "") << p.name;
  EXPECT_EQ(o.err, p.name + ": " + message + "\n") << p.name;
}

TEST(Cli, VersionAndHelp) {
  for (const Program &p : programs()) {
    Output o = run(p.exe, {"--version"});
    EXPECT_EQ(o.status, 0) << p.name;
    EXPECT_EQ(o.out, p.name + " (sba " + SBA_VERSION + ")\n");
    EXPECT_EQ(o.err, "") << p.name;
    for (const char *help : {"--help", "-h"}) {
      o = run(p.exe, {help});
      EXPECT_EQ(o.status, 0) << p.name;
      EXPECT_EQ(o.out.rfind("Usage: " + p.name + " ", 0), 0u) << p.name << ":\n" << o.out;
      for (const std::string &opt : {std::string("  --help\n"), std::string("  --version\n"), "  --" + p.int_option + "="})
        EXPECT_NE(o.out.find(opt), std::string::npos) << p.name << " --help lacks " << opt;
      EXPECT_EQ(o.err, "") << p.name;
    }
  }
}

TEST(Cli, SameMessagesForTheSameMistakes) {
  for (const Program &p : programs()) {
    const std::string opt = "--" + p.int_option;
    expect_usage_error(p, {"--bogus"}, "unknown option '--bogus' (see --help)");
    expect_usage_error(p, {"--bogus=1"}, "unknown option '--bogus' (see --help)");
    expect_usage_error(p, {"-x"}, "unknown option '-x' (options are long: see --help)");
    expect_usage_error(p, {"--version=yes"}, "option '--version' takes no value");
    expect_usage_error(p, {opt}, "option '" + opt + "' needs a value (N)");
    // Both spellings of a value, the same verdict.
    expect_usage_error(p, {opt + "=ten"}, "bad value 'ten' for " + opt + ": expected " + p.int_range);
    expect_usage_error(p, {opt, "ten"}, "bad value 'ten' for " + opt + ": expected " + p.int_range);
    expect_usage_error(p, {opt + "=-1"}, "bad value '-1' for " + opt + ": expected " + p.int_range);
    expect_usage_error(p, {opt + "="}, "bad value '' for " + opt + ": expected " + p.int_range);
    expect_usage_error(p, {opt + "=12abc"}, "bad value '12abc' for " + opt + ": expected " + p.int_range);
    // An integer too large for an int, and one too large for any integer type: "too large".
    for (const std::string big : {"2147483648", "99999999999999999999999"})
      expect_usage_error(p, {opt, big}, "bad value '" + big + "' for " + opt + ": too large: the most is 2147483647");
  }
}

// The options that the solving programs share behave the same in each.
TEST(Cli, SolverThreadsAndLossAlike) {
  for (const Program &p : programs()) {
    if (p.name != "eucsbademo" && p.name != "balsba" && p.name != "sbarefine") continue;
    expect_usage_error(p, {"--threads=257"}, "bad value '257' for --threads: expected an integer from 0 to 256");
    expect_usage_error(p, {"--threads", "-2"}, "bad value '-2' for --threads: expected an integer from 0 to 256");
    expect_usage_error(p, {"--loss", "nope"},
                       "bad value 'nope' for --loss: expected one of: none, huber, cauchy, soft-l1, tukey");
    expect_usage_error(p, {"--loss-scale=0"}, "bad value '0' for --loss-scale: expected a positive number");
    expect_usage_error(p, {"--solver=nope"},
                       std::string("bad value 'nope' for --solver: expected one of: ") + sba_linsolver_names());
    expect_usage_error(p, {"--tau=0"}, "bad value '0' for --tau: expected a positive number");
    expect_usage_error(p, {"--opts", "1,2,3"}, "bad value '1,2,3' for --opts: expected 5 comma-separated numbers");
    expect_usage_error(p, {"--mcon=-1"}, "bad value '-1' for --mcon: expected an integer >= 0");
    // Good values in both spellings are accepted (--version then ends the run before any file
    // is needed).
    for (const std::vector<std::string> &good :
         {std::vector<std::string>{"--solver=sparse-chol", "--threads=256", "--loss=huber", "--version"},
          std::vector<std::string>{"--solver", "sparse-chol", "--threads", "0", "--loss", "none", "--version"},
          std::vector<std::string>{"--opts=1e-3,1e-12,1e-12,1e-12,0", "--eps4", "1e-6", "--itmax", "5",
                                   "--mcon=1", "--ncon", "0", "--version"}}) {
      const Output o = run(p.exe, good);
      EXPECT_EQ(o.status, 0) << p.name << " " << good[0] << ": " << o.err;
      EXPECT_EQ(o.out, p.name + " (sba " + SBA_VERSION + ")\n");
    }
  }
}

#ifdef SBA_BENCH_EXE
TEST(Cli, BenchListsCheckEachItem) {
  const Program p{"sba_bench", SBA_BENCH_EXE, "itmax", ""};
  expect_usage_error(p, {"--threads=1,300"}, "bad value '1,300' for --threads: '300': expected an integer from 1 to 256");
  expect_usage_error(p, {"--solvers", "chol,nope"},
                     std::string("bad value 'chol,nope' for --solvers: 'nope': expected one of: ") +
                         sba_linsolver_names());
  expect_usage_error(p, {"--ceres=dense,x"},
                     "bad value 'dense,x' for --ceres: 'x': expected one of: dense, sparse, iterative");
  expect_usage_error(p, {"--strategy", "sba,fast"},
                     std::string("bad value 'sba,fast' for --strategy: 'fast': expected one of: ") +
                         sba_strategy_names());
}
#endif

TEST(Cli, PositionalArgumentsCounted) {
  for (const Program &p : programs()) {
    if (p.name == "eucsbademo")
      expect_usage_error(p, {"a"}, "expected 2 or 3 file arguments (cams.txt pts.txt [calib.txt]), got 1 (see --help)");
    if (p.name == "balsba") {
      expect_usage_error(p, {}, "expected 1 file argument (a BAL problem), got 0 (see --help)");
      expect_usage_error(p, {"a", "b"}, "expected 1 file argument (a BAL problem), got 2 (see --help)");
    }
    if (p.name == "sbarefine")
      expect_usage_error(p, {"a", "b"},
                         "expected 1 argument (a COLMAP model directory, a Bundler or an NVM file), got 2 (see --help)");
    if (p.name == "sbagen") {
      expect_usage_error(p, {}, "--out PREFIX is required (see --help)");
      expect_usage_error(p, {"--out=x", "extra"}, "unexpected argument 'extra' (see --help)");
    }
  }
}

// Which solver runs when none is named (docs/solvers.md): sba 1.6's chol in eucsbademo; auto
// in balsba and sbarefine, which say what it chose in the summary and in --json, and whose run
// is the chosen solver's, bit for bit. The problem: a road of 300 cameras, each point seen by
// consecutive ones, so S is banded and of about 1800 unknowns, beyond the size auto gives chol.
TEST(Cli, DefaultSolverOfEachProgram) {
  unsetenv("SBA_LINSOLVER");
  const std::string dir = sbatest::scratch_dir() + "test_cli_solver." + std::to_string(getpid());
  ASSERT_EQ(std::system(("rm -rf '" + dir + "' && mkdir -p '" + dir + "/auto' '" + dir + "/named'").c_str()), 0);
  const std::string gen = dir + "/gen";
  Output o = run(SBAGEN_EXE, {"--out", gen, "--trajectory", "path", "--cameras", "300", "--points", "3000",
                              "--colmap-binary", dir + "/model", "--bundler", dir + "/bundle.out", "--quiet"});
  ASSERT_EQ(o.status, 0) << o.err;
  o = run(SBAREFINE_EXE, {dir + "/bundle.out", "--itmax", "0", "--write-bal", dir + "/problem.bal", "--no-progress"});
  ASSERT_EQ(o.status, 0) << o.err;
  const auto solver_line = [](const std::string &out) {
    const std::size_t at = out.find("\nSolver ");
    return at == std::string::npos ? std::string() : out.substr(at + 1, out.find(" on ", at) - at - 1);
  };
  // eucsbademo: chol, asked for by no one; auto when asked.
  const std::vector<std::string> files{gen + "-cams.txt", gen + "-pts.txt", gen + "-calib.txt"};
  std::vector<std::string> args = files;
  args.insert(args.end(), {"--itmax", "1", "--json", dir + "/e.json"});
  o = run(EUCSBADEMO_EXE, args);
  ASSERT_EQ(o.status, 0) << o.err;
  EXPECT_EQ(solver_line(o.out), "Solver chol");
  std::string json = slurp(dir + "/e.json");
  EXPECT_NE(json.find("\"options\": {\"solver\": null, "), std::string::npos) << json.substr(0, 600);
  EXPECT_NE(json.find("\n  \"solver\": \"chol\",\n"), std::string::npos);
  args.push_back("--solver=auto");
  o = run(EUCSBADEMO_EXE, args);
  ASSERT_EQ(o.status, 0) << o.err;
  EXPECT_EQ(solver_line(o.out), "Solver sparse-chol (auto)");
  json = slurp(dir + "/e.json");
  EXPECT_NE(json.find("\"options\": {\"solver\": \"auto\", "), std::string::npos) << json.substr(0, 600);
  EXPECT_NE(json.find("\n  \"solver\": \"sparse-chol\",\n"), std::string::npos);
  // balsba and sbarefine: auto, which writes what sparse-chol writes.
  const struct {
    const char *exe, *input, *written;
  } programs[] = {{BALSBA_EXE, "/problem.bal", "/refined.bal"}, {SBAREFINE_EXE, "/model", ""}};
  for (const auto &p : programs) {
    for (const char *how : {"auto", "named"}) {
      std::vector<std::string> a{dir + p.input, "--itmax", "2", "--no-progress", "--json", dir + "/" + how + ".json",
                                 "--write", dir + "/" + how + p.written};
      if (std::string(how) == "named") a.insert(a.end(), {"--solver", "sparse-chol"});
      o = run(p.exe, a);
      ASSERT_EQ(o.status, 0) << p.exe << " " << how << ": " << o.err;
      json = slurp(dir + "/" + how + ".json");
      EXPECT_NE(json.find("\n  \"solver\": \"sparse-chol\",\n"), std::string::npos) << p.exe << " " << how;
      if (std::string(how) == "auto") {
        EXPECT_EQ(solver_line(o.out), "Solver sparse-chol (auto)") << p.exe << o.out;
        EXPECT_NE(json.find("\"options\": {\"solver\": \"auto\", "), std::string::npos) << p.exe;
      } else {
        EXPECT_EQ(solver_line(o.out), "Solver sparse-chol") << p.exe << o.out;
      }
    }
    for (const std::string f : {"/refined.bal", "/cameras.bin", "/images.bin", "/points3D.bin"}) {
      if ((f == "/refined.bal") != (std::string(p.written) == "/refined.bal")) continue;
      const std::string by_auto = slurp(dir + "/auto" + f), named = slurp(dir + "/named" + f);
      EXPECT_FALSE(by_auto.empty()) << f;
      EXPECT_TRUE(by_auto == named) << p.exe << f << ": auto's result is not sparse-chol's";
    }
  }
  EXPECT_EQ(std::system(("rm -rf '" + dir + "'").c_str()), 0);
}

// sbarefine takes the format from the file and refuses, before reading it through, the options
// of other formats.
TEST(Cli, SbarefineOptionsOfAnotherFormat) {
  const Program p{"sbarefine", SBAREFINE_EXE, "itmax", ""};
  const std::string nvm = sbatest::scratch_dir() + "test_cli." + std::to_string(getpid()) + ".nvm";
  std::ofstream(nvm) << "NVM_V3\n\n1\na.jpg 500 1 0 0 0 0 0 -5 0 0\n1\n0 0 0 1 2 3 1 0 0 1 2\n";
  expect_usage_error(p, {"--write-format=binary", nvm}, "--write-format is for COLMAP models");
  expect_usage_error(p, {"--write-bal", "x.bal", nvm}, "--write-bal is for Bundler files");
  for (const char *option : {"--hold-intrinsics", "--hold-sensor-from-rig", "--hold-points"})
    expect_usage_error(p, {option, "1", nvm}, std::string(option) + " is for COLMAP models");
  expect_usage_error(p, {"--hold-points-file", "ids.txt", nvm}, "--hold-points-file is for COLMAP models");
  expect_usage_error(p, {"--covariance", "cov.txt", nvm}, "--covariance is for COLMAP models");
  for (const std::vector<std::string> &args : {std::vector<std::string>{"--covariance-points", nvm},
                                               std::vector<std::string>{"--covariance-damping", "1e-8", nvm}})
    expect_usage_error(p, args, "--covariance-points and --covariance-damping are for --covariance, which is not given");
  expect_usage_error(p, {"--intrinsics=all", nvm},
                     "--intrinsics all: an NVM file has no principal point (its measurements are relative to the "
                     "image centre)");
  std::remove(nvm.c_str());
}

// A PLY file that cannot be written stops each program before its solve: status 1, the path
// and the reason on stderr, nothing on stdout.
TEST(Cli, UnwritablePlyStopsEveryProgramBeforeTheSolve) {
  const std::string nowhere = sbatest::scratch_dir() + "test_cli.no-such-dir/x.ply";
  const std::string data = std::string(SBA_PROJECT_DIR) + "/data/orbit-fixedK-";
  const std::pair<std::string, std::vector<std::string>> kRuns[] = {
      {EUCSBADEMO_EXE, {data + "cams.txt", data + "pts.txt", data + "calib.txt"}},
      {BALSBA_EXE, {"problem.txt"}},
      {SBAREFINE_EXE, {"model"}}};
  for (const auto &[exe, inputs] : kRuns)
    for (const char *option : {"--initial-ply", "--final-ply"}) {
      SCOPED_TRACE(exe + " " + option);
      std::vector<std::string> args{option, nowhere};
      args.insert(args.end(), inputs.begin(), inputs.end());
      const Output o = run(exe, args);
      EXPECT_EQ(o.status, 1);
      EXPECT_EQ(o.out, "");
      EXPECT_EQ(o.err, nowhere + ": cannot open for writing: No such file or directory\n");
    }
}

// Each program under an address-space limit (ulimit -v), from one too small to load the shared
// libraries to one with room to spare, with OpenBLAS's thread count left to OpenBLAS: it ends,
// within a minute, with its answer (status 0), a clean failure (status 1 and one line), or the
// dynamic loader's refusal to map a library (127) before the program runs; never killed by a
// signal or hung at exit (a timeout kills it: status 137). On a machine of one core OpenBLAS
// starts no worker thread, and the limit changes less.
TEST(Cli, EveryProgramEndsUnderAnyAddressSpaceLimit) {
#ifdef SBA_TEST_SANITIZED
  GTEST_SKIP() << "RLIMIT_AS cannot work under a sanitizer (it reserves terabytes of shadow memory)";
#endif
  const std::string data = std::string(SBA_PROJECT_DIR) + "/data/orbit-fixedK-";
  std::vector<std::pair<std::string, std::vector<std::string>>> runs;
  for (const Program &p : programs()) runs.push_back({p.name, {p.exe, "--version"}});
  runs.push_back({"eucsbademo", {EUCSBADEMO_EXE, data + "cams.txt", data + "pts.txt", data + "calib.txt"}});
  for (const long long mib : {40, 48, 56, 64, 80, 96, 128, 160, 200, 256, 512}) {
    for (const auto &[name, words] : runs) {
      std::string inner = "ulimit -v " + std::to_string(mib * 1024) + "; exec";
      for (const std::string &w : words) inner += " '" + w + "'";
      const Output o = run("/usr/bin/env", {"-u", "OPENBLAS_NUM_THREADS", "-u", "GOTO_NUM_THREADS", "-u",
                                            "OMP_NUM_THREADS", "timeout", "-s", "KILL", "60", "sh", "-c", inner});
      SCOPED_TRACE(name + " " + words.back() + " under " + std::to_string(mib) + " MiB");
      if (o.status == 127) {
        EXPECT_NE(o.err.find("error while loading shared libraries"), std::string::npos) << o.err;
        continue;
      }
      // A clean failure ends with the program's one line; what it printed before (eucsbademo's
      // "Starting BA ..." and the library's "out of memory", as 1.6 prints them) may precede it.
      const std::size_t last = o.err.rfind('\n', o.err.size() >= 2 ? o.err.size() - 2 : 0);
      const std::string last_line = o.err.substr(last == std::string::npos ? 0 : last + 1);
      EXPECT_TRUE(o.status == 0 || (o.status == 1 && last_line.rfind(name + ": ", 0) == 0 &&
                                    !o.err.empty() && o.err.back() == '\n'))
          << "status " << o.status << "\n" << o.err;
      if (o.status == 0 && words.back() == "--version") EXPECT_EQ(o.out, name + " (sba " + SBA_VERSION + ")\n");
      if (o.status == 0 && words.back() != "--version") EXPECT_NE(o.out.find("SBA returned"), std::string::npos);
    }
  }
}

// eucsbademo reads bzip2-compressed files and one of its files from standard input ('-').
class EucsbademoInputs : public ::testing::Test {
 protected:
  static std::string data(const char *part) { return std::string(SBA_PROJECT_DIR) + "/data/orbit-fixedK-" + part + ".txt"; }
  // Writes path + ".bz2" compressed with libbz2, or only its first `keep` bytes.
  static std::string compress(const std::string &path, const std::string &to, std::size_t keep = SIZE_MAX) {
    const std::string text = slurp(path);
    std::vector<char> out(text.size() + text.size() / 100 + 600);
    unsigned int len = static_cast<unsigned int>(out.size());
    EXPECT_EQ(BZ2_bzBuffToBuffCompress(out.data(), &len, const_cast<char *>(text.data()),
                                       static_cast<unsigned int>(text.size()), 9, 0, 0),
              BZ_OK);
    std::ofstream(to, std::ios::binary).write(out.data(), std::min<std::size_t>(len, keep));
    return to;
  }
  // The lines of a summary that do not depend on the time taken.
  static std::string timeless(const std::string &out) {
    std::string kept;
    std::size_t start = 0;
    while (start < out.size()) {
      const std::size_t nl = out.find('\n', start);
      const std::string line = out.substr(start, nl - start);
      if (line.rfind("Elapsed time:", 0) != 0 && line.rfind("Solver ", 0) != 0) kept += line + "\n";
      start = nl == std::string::npos ? out.size() : nl + 1;
    }
    return kept;
  }
};

TEST_F(EucsbademoInputs, Bzip2AndStandardInputGiveTheSameRun) {
  const std::string tmp = sbatest::scratch_dir() + "test_cli." + std::to_string(getpid());
  const Output plain = run(EUCSBADEMO_EXE, {"--threads=1", data("cams"), data("pts"), data("calib")});
  ASSERT_EQ(plain.status, 0) << plain.err;
  ASSERT_NE(plain.out.find("SBA returned"), std::string::npos);
  const std::string cams = compress(data("cams"), tmp + "-cams.txt.bz2");
  const std::string pts = compress(data("pts"), tmp + "-pts.txt.bz2");
  const Output z = run(EUCSBADEMO_EXE, {"--threads=1", cams, pts, data("calib")});
  EXPECT_EQ(z.status, 0) << z.err;
  EXPECT_EQ(timeless(z.out), timeless(plain.out));
  const std::pair<std::size_t, const char *> kFiles[] = {{1, "cams"}, {2, "pts"}, {3, "calib"}};
  for (const auto &[at, part] : kFiles) {
    std::vector<std::string> args{"--threads=1", data("cams"), data("pts"), data("calib")};
    args[at] = "-";
    const Output in = run(EUCSBADEMO_EXE, args, data(part));
    EXPECT_EQ(in.status, 0) << part << ": " << in.err;
    EXPECT_EQ(timeless(in.out), timeless(plain.out)) << part;
  }
  const Output twice = run(EUCSBADEMO_EXE, {"-", "-"});
  EXPECT_EQ(twice.status, 2);
  EXPECT_EQ(twice.err, "eucsbademo: standard input ('-') can be only one of the files\n");
  // A damaged compressed file is one line naming it, like any bad file.
  const std::string cut = compress(data("pts"), tmp + "-cut.txt.bz2", 2000);
  const Output bad = run(EUCSBADEMO_EXE, {data("cams"), cut, data("calib")});
  EXPECT_EQ(bad.status, 1);
  EXPECT_EQ(bad.out, "");
  EXPECT_EQ(bad.err, cut + ":1: the bzip2 data end too early (truncated file)\n");
  for (const std::string &f : {cams, pts, cut}) std::remove(f.c_str());
}

}  // namespace
