// The command-line conventions of the four programs (demo/cli.h), checked on the programs
// themselves: the same grammar (--opt=VALUE and --opt VALUE), --help and --version in each,
// and the same one-line message and exit status for the same mistake.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "sba.h"
#include "sba_ext.h"

namespace {

struct Program {
  std::string name, exe;
  std::string int_option;  // an integer option >= 0 (or >= 1) with no upper bound of its own
  std::string int_range;   // what the message says about it
};

std::vector<Program> programs() {
  std::vector<Program> p{{"eucsbademo", EUCSBADEMO_EXE, "itmax", "an integer >= 0"},
                         {"balsba", BALSBA_EXE, "itmax", "an integer >= 0"},
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

// Runs exe with args (each passed as one word) and captures stdout, stderr and the status.
Output run(const std::string &exe, const std::vector<std::string> &args) {
  const std::string base = ::testing::TempDir() + "test_cli." + std::to_string(getpid());
  std::string cmd = "exec '" + exe + "'";
  for (const std::string &a : args) cmd += " '" + a + "'";
  cmd += " >" + base + ".out 2>" + base + ".err </dev/null";
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
    if (p.name != "eucsbademo" && p.name != "balsba") continue;
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
  expect_usage_error(p, {"--ceres=dense,x"}, "bad value 'dense,x' for --ceres: 'x': expected one of: dense, sparse");
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
    if (p.name == "sbagen") {
      expect_usage_error(p, {}, "--out PREFIX is required (see --help)");
      expect_usage_error(p, {"--out=x", "extra"}, "unexpected argument 'extra' (see --help)");
    }
  }
}

}  // namespace
