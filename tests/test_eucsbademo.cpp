// SPDX-License-Identifier: BSD-3-Clause
// eucsbademo as its users run it: the real executable (EUCSBADEMO_EXE), its stdout and stderr
// captured separately, on sba 1.6's demo data (the published results, checked-in golden
// output, every linear solver, the other drivers and refinements, a round trip through the
// files it writes) and on bad command lines and bad files; then its option parser directly.
//
// Formats: docs/formats.md. Tests that need the shared data skip when it is absent.
//
// Environment:
//   SBA_LONG_TESTS=1     also run the slow solver cases (minutes; see "Every linear solver").
//   SBA_UPDATE_GOLDEN=1  rewrite tests/golden/*.out from the current output instead of
//                        comparing (then review the diff before committing it).
// The child never inherits SBA_LINSOLVER unless a test sets it: these tests check the defaults.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "eucsbademo/options.h"
#include "formats/eucsba_io.h"
#include "ply_file.h"
#include "sanitized.h"
#include "sba_ext.h"

namespace eucsba = sbaformats::eucsba;

#ifndef EUCSBADEMO_EXE
#error "EUCSBADEMO_EXE must name the eucsbademo executable"
#endif

extern char **environ;

namespace fs = std::filesystem;

namespace {

// ---------------------------------------------------------------------------------------------
// Running the executable

std::string demo_dir() { return std::string(SBA_SHARED_DATA_DIR) + "/sba-demo"; }
std::string demo_file(const std::string &name) { return demo_dir() + "/" + name; }
std::string golden_path(const std::string &name) {
  return std::string(SBA_PROJECT_DIR) + "/tests/golden/" + name + ".out";
}

bool env_flag(const char *name) {
  const char *v = std::getenv(name);
  return v && *v && std::strcmp(v, "0") != 0;
}

#define REQUIRE_DEMO_DATA()                                                              \
  do {                                                                                   \
    if (!fs::is_directory(demo_dir())) GTEST_SKIP() << "no shared demo data at " << demo_dir(); \
  } while (0)

// A directory removed with everything in it at the end of its scope.
class TempDir {
 public:
  TempDir() {
    static int counter = 0;
    const ::testing::TestInfo *info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = info ? std::string(info->test_suite_name()) + "_" + info->name() : "x";
    std::replace(name.begin(), name.end(), '/', '_');
    path_ = fs::temp_directory_path() /
            ("eucsbademo_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + "_" + name);
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir &) = delete;
  TempDir &operator=(const TempDir &) = delete;

  std::string file(const std::string &name) const { return (path_ / name).string(); }
  std::string write(const std::string &name, const std::string &text) const {
    const std::string p = file(name);
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }

 private:
  fs::path path_;
};

std::string read_text(const std::string &path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::vector<std::string> split_lines(const std::string &text) {
  std::vector<std::string> lines;
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t nl = text.find('\n', start);
    if (nl == std::string::npos) nl = text.size();
    lines.push_back(text.substr(start, nl - start));
    start = nl + 1;
  }
  return lines;
}

struct DemoRun {
  int status = -1;  // exit status; -1 when the child did not exit normally
  int signal = 0;   // the signal that ended it, if one did
  std::string out, err;
  std::vector<std::string> err_lines() const { return split_lines(err); }
  std::vector<std::string> out_lines() const { return split_lines(out); }
};

std::ostream &operator<<(std::ostream &os, const DemoRun &r) {
  return os << "exit status " << r.status << (r.signal ? " (signal " + std::to_string(r.signal) + ")" : "")
            << "\n--- stdout ---\n" << r.out << "--- stderr ---\n" << r.err;
}

// Variables to set (a value) or remove (nullopt) in the child's environment.
using EnvChanges = std::vector<std::pair<std::string, std::optional<std::string>>>;

// What a run may change about the child: where stdout goes, and resource limits (bytes).
struct ChildSetup {
  std::string stdout_to;               // empty: captured in DemoRun::out
  rlim_t file_size = RLIM_INFINITY;    // RLIMIT_FSIZE; SIGXFSZ is then ignored, writes fail
  rlim_t address_space = RLIM_INFINITY;  // RLIMIT_AS
  unsigned alarm_seconds = 0;            // nonzero: SIGALRM ends a child that takes longer
};

// Runs eucsbademo with args, stdin from /dev/null, stdout and stderr into separate files.
DemoRun run_demo(const std::vector<std::string> &args, const EnvChanges &env = {},
                 const ChildSetup &setup = {}) {
  DemoRun r;
  TempDir dir;
  const std::string out_path = setup.stdout_to.empty() ? dir.file("stdout") : setup.stdout_to;
  const std::string err_path = dir.file("stderr");

  std::vector<std::string> argv_s{EUCSBADEMO_EXE};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char *> argv;
  for (std::string &a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);

  // The parent's environment without SBA_LINSOLVER and the variables env changes.
  EnvChanges changes = env;
  if (std::none_of(changes.begin(), changes.end(), [](const auto &c) { return c.first == "SBA_LINSOLVER"; }))
    changes.emplace_back("SBA_LINSOLVER", std::nullopt);
  std::vector<std::string> env_s;
  for (char **e = environ; *e; ++e) {
    const std::string entry = *e;
    const std::string name = entry.substr(0, entry.find('='));
    if (std::none_of(changes.begin(), changes.end(), [&](const auto &c) { return c.first == name; }))
      env_s.push_back(entry);
  }
  for (const auto &c : changes)
    if (c.second) env_s.push_back(c.first + "=" + *c.second);
  std::vector<char *> envp;
  for (std::string &e : env_s) envp.push_back(e.data());
  envp.push_back(nullptr);

  pid_t pid = 0;
  const bool limited =
      setup.file_size != RLIM_INFINITY || setup.address_space != RLIM_INFINITY || setup.alarm_seconds != 0;
  if (!limited) {
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 1, out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    posix_spawn_file_actions_addopen(&actions, 2, err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    const int rc = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), envp.data());
    posix_spawn_file_actions_destroy(&actions);
    if (rc != 0) {
      ADD_FAILURE() << "cannot start " << argv[0] << ": " << std::strerror(rc);
      return r;
    }
  } else {
    // posix_spawn sets no limits: fork, and in the child only async-signal-safe calls.
    const int in = ::open("/dev/null", O_RDONLY);
    const int out = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    const int err = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    if (in < 0 || out < 0 || err < 0) {
      ADD_FAILURE() << "cannot open the child's standard files";
      return r;
    }
    pid = ::fork();
    if (pid == 0) {
      ::dup2(in, 0);
      ::dup2(out, 1);
      ::dup2(err, 2);
      if (setup.file_size != RLIM_INFINITY) {
        ::signal(SIGXFSZ, SIG_IGN);  // ignored signals stay ignored across exec
        const rlimit lim{setup.file_size, setup.file_size};
        ::setrlimit(RLIMIT_FSIZE, &lim);
      }
#ifndef SBA_TEST_SANITIZED
      if (setup.address_space != RLIM_INFINITY) {
        const rlimit lim{setup.address_space, setup.address_space};
        ::setrlimit(RLIMIT_AS, &lim);
      }
#endif
      if (setup.alarm_seconds != 0) ::alarm(setup.alarm_seconds);  // kept across exec
      ::execve(argv[0], argv.data(), envp.data());
      ::_exit(127);
    }
    ::close(in);
    ::close(out);
    ::close(err);
    if (pid < 0) {
      ADD_FAILURE() << "fork: " << std::strerror(errno);
      return r;
    }
  }
  int wstatus = 0;
  while (::waitpid(pid, &wstatus, 0) < 0 && errno == EINTR) {
  }
  if (WIFEXITED(wstatus)) r.status = WEXITSTATUS(wstatus);
  if (WIFSIGNALED(wstatus)) r.signal = WTERMSIG(wstatus);
  if (setup.stdout_to.empty()) r.out = read_text(out_path);
  r.err = read_text(err_path);
  return r;
}

// ---------------------------------------------------------------------------------------------
// What a successful run prints

// stdout of a successful run, parsed (the line formats of the spec, 1.6's printf formats).
struct Summary {
  bool parsed = false;
  int npoints = 0, nframes = 0, nprojs = 0;
  long long nvars = 0;
  std::string method_line;
  int ret = 0;
  std::string iters, reason;      // printed with %g
  std::string error, initial;     // printed with %g: info[1] / nprojs and info[0] / nprojs
  int nfunc = 0, njac = 0, nlin = 0;
  std::string elapsed_line;

  int iterations() const { return std::atoi(iters.c_str()); }
  int reason_code() const { return std::atoi(reason.c_str()); }
  double error_value() const { return std::strtod(error.c_str(), nullptr); }
  double initial_value() const { return std::strtod(initial.c_str(), nullptr); }
};

const std::regex kUsingLine(
    R"(SBA using (\d+) 3D pts, (\d+) frames and (\d+) image projections, (\d+) variables)");
const std::regex kReturnedLine(
    R"(SBA returned (-?\d+) in (\S+) iter, reason (\S+), error (\S+) \[initial ([^\]\s]+)\], )"
    R"((\d+)/(\d+) func/fjac evals, (\d+) lin\. systems)");
const std::regex kElapsedLine(R"(Elapsed time: \d+\.\d\d seconds, \d+\.\d\d msecs)");

// The lines after sba 1.6's: the RMS reprojection error, the stop reason in words, the solver.
const std::regex kRmsLine(R"(RMS reprojection error: initial \S+ px, final \S+ px)");
const std::regex kStopLine(R"(Stop reason (\d+): .+)");
const std::regex kSolverLine(R"(Solver \S+( \(auto\))? on \d+ threads?(, strategy \S+)?, \d+\.\d\d\d s)");

// How many lines at the end of out are the report after sba 1.6's lines (0 if they are not
// there, or not in order).
std::size_t report_lines(const std::vector<std::string> &lines) {
  const std::size_t n = lines.size();
  if (n < 3 || !std::regex_match(lines[n - 3], kRmsLine) || !std::regex_match(lines[n - 2], kStopLine) ||
      !std::regex_match(lines[n - 1], kSolverLine))
    return 0;
  return 3;
}

// Exactly the six lines of the spec, in order, then the report.
Summary parse_summary(const std::string &out) {
  Summary s;
  std::vector<std::string> lines = split_lines(out);
  if (report_lines(lines) != 3) return s;
  lines.resize(lines.size() - 3);
  if (lines.size() != 6 || !lines[1].empty() || !lines[3].empty()) return s;
  std::smatch m;
  if (!std::regex_match(lines[0], m, kUsingLine)) return s;
  s.npoints = std::stoi(m[1]);
  s.nframes = std::stoi(m[2]);
  s.nprojs = std::stoi(m[3]);
  s.nvars = std::stoll(m[4]);
  if (lines[2].rfind("Method ", 0) != 0) return s;
  s.method_line = lines[2];
  if (!std::regex_match(lines[4], m, kReturnedLine)) return s;
  s.ret = std::stoi(m[1]);
  s.iters = m[2];
  s.reason = m[3];
  s.error = m[4];
  s.initial = m[5];
  s.nfunc = std::stoi(m[6]);
  s.njac = std::stoi(m[7]);
  s.nlin = std::stoi(m[8]);
  if (!std::regex_match(lines[5], kElapsedLine)) return s;
  s.elapsed_line = lines[5];
  s.parsed = true;
  return s;
}

// Whether a printed value agrees with a reference to `digits` significant digits: within one
// unit of the last of those digits (two values on either side of a rounding boundary print
// differently in the last digit; anything further apart differs).
bool same_to_digits(const std::string &printed, const std::string &reference, int digits) {
  const double a = std::strtod(printed.c_str(), nullptr), b = std::strtod(reference.c_str(), nullptr);
  if (!std::isfinite(a) || !std::isfinite(b) || b == 0.0) return printed == reference;
  const double unit = std::pow(10.0, std::floor(std::log10(std::fabs(b))) - (digits - 1));
  return std::fabs(a - b) <= unit * (1.0 + 1e-9);
}

// info[6] of a solve that stopped because it converged: 1 small gradient, 2 small step,
// 4 small relative reduction (at eps4 = 0, sba 1.6's test fires through rounding once the
// decrease is tiny), 5 small error, 6 damping exhausted. Not 3 (itmax) or 7 (NaN/Inf).
bool converged(const Summary &s) {
  const int r = s.reason_code();
  return s.reason == std::to_string(r) && (r == 1 || r == 2 || r == 4 || r == 5 || r == 6);
}

// A successful run: exit 0, the banner alone on stderr, the six lines on stdout.
#define EXPECT_SUCCESSFUL_RUN(run, banner, summary)                              \
  do {                                                                           \
    ASSERT_EQ((run).status, 0) << (run);                                         \
    EXPECT_EQ((run).err, std::string(banner) + "\n") << (run);                   \
    (summary) = parse_summary((run).out);                                        \
    ASSERT_TRUE((summary).parsed) << "unexpected stdout:\n" << (run).out;        \
  } while (0)

const char *const kFixedBanner = "Starting BA with fixed intrinsic parameters";
const char *const kVaryingBanner = "Starting BA with varying intrinsic parameters";
const char *const kDistortionBanner = "Starting BA with varying intrinsic parameters & distortion";

// The shared demo problems.
struct DemoProblem {
  const char *name;  // also the golden file's name
  const char *cams, *pts, *calib;  // calib empty for per-camera intrinsics
  const char *banner;
  int npoints, nframes, nprojs, cnp;
};

const DemoProblem k7cams{"7cams", "7cams.txt", "7pts.txt", "calib.txt", kFixedBanner, 465, 7, 1916, 6};
const DemoProblem k9cams{"9cams", "9cams.txt", "9pts.txt", "calib.txt", kFixedBanner, 559, 9, 2422, 6};
const DemoProblem k54cams{"54cams", "54cams.txt", "54pts.txt", "calib.txt", kFixedBanner, 5207, 54, 24609, 6};
const DemoProblem k7camsvarK{"7camsvarK", "7camsvarK.txt", "7pts.txt", "", kVaryingBanner, 465, 7, 1916, 11};
const DemoProblem k9camsvarK{"9camsvarK", "9camsvarK.txt", "9pts.txt", "", kVaryingBanner, 559, 9, 2422, 11};
const DemoProblem k54camsvarK{"54camsvarK", "54camsvarK.txt", "54pts.txt", "", kVaryingBanner,
                              5207, 54, 24609, 11};
const DemoProblem k54camsvarKD{"54camsvarKD", "54camsvarKD.txt", "54pts.txt", "", kDistortionBanner,
                               5207, 54, 24609, 16};

std::vector<std::string> problem_args(const DemoProblem &p) {
  std::vector<std::string> args{demo_file(p.cams), demo_file(p.pts)};
  if (*p.calib) args.push_back(demo_file(p.calib));
  return args;
}

DemoRun run_problem(const DemoProblem &p, std::vector<std::string> options, const EnvChanges &env = {}) {
  const std::vector<std::string> files = problem_args(p);
  options.insert(options.end(), files.begin(), files.end());
  return run_demo(options, env);
}

long long motstr_vars(const DemoProblem &p) {
  return static_cast<long long>(p.nframes) * p.cnp + 3LL * p.npoints;
}

// ---------------------------------------------------------------------------------------------
// a + b. The sba 1.6 distribution's published runs, and our golden output of the same runs
// (one run serves both checks: the 54-camera problems take seconds each).

struct PublishedRun {
  DemoProblem problem;
  long long nvars;      // the spec's table
  const char *error;    // sba 1.6's published figures (%g)
  const char *initial;
  const char *method;   // the Method line
};

const char *const kMethodFixed =
    "Method BA_MOTSTRUCT, expert driver, analytic Jacobian, without covariances, without distortion, "
    "fixed intrinsics";
const char *const kMethodVarK =
    "Method BA_MOTSTRUCT, expert driver, analytic Jacobian, without covariances, without distortion, "
    "variable intrinsics (2 fixed)";
const char *const kMethodVarKD =
    "Method BA_MOTSTRUCT, expert driver, analytic Jacobian, without covariances, variable distortion "
    "(3 fixed), variable intrinsics (2 fixed)";

const PublishedRun kPublished[] = {
    {k7cams, 1437, "0.675396", "19.0947", kMethodFixed},
    {k9cams, 1731, "0.619559", "8.17604", kMethodFixed},
    {k54cams, 15945, "0.176473", "2.14707", kMethodFixed},
    {k54camsvarK, 16215, "0.134928", "2.14707", kMethodVarK},
    {k54camsvarKD, 16485, "0.128779", "2.14707", kMethodVarKD},
};

// Golden comparison. Text must match exactly; on the "SBA returned" line the errors may differ
// by a relative 1e-5, and the counts by a little, because iteration and evaluation counts
// depend on rounding: a faster library that orders its sums differently, or another
// BLAS/LAPACK kernel, takes a few more or fewer steps to the same minimum (1.6's own 54cams run
// takes 17 to 22 iterations over its builds, thread counts and OpenBLAS kernels). So the
// returned value, the iterations and the Jacobian evaluations may differ by max(2, 25%) of the
// golden count. The trial counts (function evaluations, linear systems) are the iterations
// plus the rejected attempts, which come and go with the path (1.6's own 9cams runs solve 15
// to 28 systems in 15 to 20 iterations): each is checked against the run's own iterations,
// one per iteration at least (a run that stop 2 ends may not evaluate its last step), at
// most twice as many plus kStopTwoTail. The reason must be a convergence stop; 2 and 4 stand for each other, since
// which of the two ends a run at the minimum is a matter of rounding (1.6's stop 4 fires on
// about one tiny step in four, and the ASan build, compiled otherwise, ends runs differently
// from the release build). A run that stop 2 ends has first grown the damping through a
// series of rejected attempts, up to kStopTwoTail more trials.
int count_slack(int golden) { return std::max(2, static_cast<int>(std::ceil(0.25 * golden))); }
constexpr int kStopTwoTail = 10;

void expect_counts_near(const char *what, int actual, int golden, int slack) {
  EXPECT_LE(std::abs(actual - golden), slack)
      << what << ": " << actual << ", golden " << golden << " (allowed difference " << slack << ")";
}

void expect_matches_golden(const std::string &out, const std::string &golden_file) {
  std::vector<std::string> actual = split_lines(out);
  // The report after sba 1.6's lines carries a time: its lines are checked by format.
  ASSERT_EQ(report_lines(actual), 3u) << out;
  actual.resize(actual.size() - 3);
  ASSERT_FALSE(actual.empty());
  // The Elapsed line is the last of 1.6's; only its format is checked.
  EXPECT_TRUE(std::regex_match(actual.back(), kElapsedLine)) << actual.back();
  actual.pop_back();

  if (env_flag("SBA_UPDATE_GOLDEN")) {
    std::ofstream f(golden_file, std::ios::binary);
    for (const std::string &line : actual) f << line << "\n";
    ASSERT_TRUE(f.good()) << "cannot write " << golden_file;
    std::printf("updated %s\n", golden_file.c_str());
    return;
  }
  ASSERT_TRUE(fs::exists(golden_file)) << golden_file << " is missing (SBA_UPDATE_GOLDEN=1 creates it)";
  const std::vector<std::string> golden = split_lines(read_text(golden_file));
  ASSERT_EQ(actual.size(), golden.size()) << "actual:\n" << out;
  for (std::size_t k = 0; k < golden.size(); ++k) {
    SCOPED_TRACE("line " + std::to_string(k + 1) + " of " + golden_file);
    std::smatch g, a;
    if (!std::regex_match(golden[k], g, kReturnedLine)) {
      EXPECT_EQ(actual[k], golden[k]);
      continue;
    }
    ASSERT_TRUE(std::regex_match(actual[k], a, kReturnedLine)) << actual[k];
    const auto near = [&](const char *what, int field) {
      expect_counts_near(what, std::stoi(a[field]), std::stoi(g[field]), count_slack(std::stoi(g[field])));
    };
    near("returned", 1);
    near("iterations", 2);
    const bool two_or_four = (a[3] == "2" || a[3] == "4") && (g[3] == "2" || g[3] == "4");
    EXPECT_TRUE(a[3] == g[3] || two_or_four) << "reason " << a[3] << ", golden " << g[3];
    const int iterations = std::stoi(a[2]);
    const auto trials = [&](const char *what, int field) {
      const int n = std::stoi(a[field]);
      EXPECT_GE(n, iterations) << what << " in " << iterations << " iterations";
      EXPECT_LE(n, 2 * iterations + kStopTwoTail) << what << " in " << iterations << " iterations";
    };
    for (int f : {4, 5}) {
      const double av = std::stod(a[f]), gv = std::stod(g[f]);
      EXPECT_LE(std::fabs(av - gv), 1e-5 * std::fabs(gv))
          << (f == 4 ? "error " : "initial error ") << a[f] << ", golden " << g[f];
    }
    trials("function evaluations", 6);
    near("Jacobian evaluations", 7);
    trials("linear systems", 8);
  }
}

void PrintTo(const PublishedRun &r, std::ostream *os) { *os << r.problem.name; }

class Published : public ::testing::TestWithParam<PublishedRun> {};

TEST_P(Published, MatchesSba16AndGoldenOutput) {
  REQUIRE_DEMO_DATA();
  const PublishedRun &pr = GetParam();
  const DemoProblem &p = pr.problem;
  const DemoRun run = run_problem(p, {});
  ASSERT_EQ(run.status, 0) << run;

  // a. sba 1.6: the banner first (and alone) on stderr, the counts, the published errors.
  const std::vector<std::string> err = run.err_lines();
  ASSERT_FALSE(err.empty()) << run;
  EXPECT_EQ(err.front(), p.banner);
  EXPECT_EQ(err.size(), 1u) << run;
  const Summary s = parse_summary(run.out);
  ASSERT_TRUE(s.parsed) << run;
  EXPECT_EQ(s.npoints, p.npoints);
  EXPECT_EQ(s.nframes, p.nframes);
  EXPECT_EQ(s.nprojs, p.nprojs);
  EXPECT_EQ(s.nvars, pr.nvars);
  EXPECT_EQ(s.nvars, motstr_vars(p));
  EXPECT_EQ(s.method_line, pr.method);
  EXPECT_TRUE(same_to_digits(s.error, pr.error, 6)) << s.error << " vs sba 1.6's " << pr.error;
  EXPECT_TRUE(same_to_digits(s.initial, pr.initial, 6)) << s.initial << " vs sba 1.6's " << pr.initial;
  EXPECT_TRUE(converged(s)) << "reason " << s.reason;
  EXPECT_EQ(std::to_string(s.ret), s.iters);
  EXPECT_EQ(s.njac, s.iterations());
  EXPECT_GE(s.nfunc, s.iterations());
  EXPECT_GE(s.nlin, s.iterations());
  if (p.nframes == 54 && p.cnp == 6) {
    EXPECT_GE(s.iterations(), 14);
    EXPECT_LE(s.iterations(), 28);
  }

  // b. The checked-in output of this implementation, and of its sba-clean-retry strategy
  // (the same lines, but for the counts and iterations its retries give).
  expect_matches_golden(run.out, golden_path(p.name));
  const DemoRun clean = run_problem(p, {"--strategy=sba-clean-retry"});
  ASSERT_EQ(clean.status, 0) << clean;
  expect_matches_golden(clean.out, golden_path(std::string(p.name) + "-sba-clean-retry"));
}

INSTANTIATE_TEST_SUITE_P(Eucsbademo, Published, ::testing::ValuesIn(kPublished),
                         [](const ::testing::TestParamInfo<PublishedRun> &info) {
                           return std::string(info.param.problem.name);
                         });

// sba 1.6's own demo on the seven problems, as 1.6 itself runs on this machine kind: built
// plain (-O2) and with FMA contraction, each with OpenBLAS at 1 and 2 threads under five of
// OpenBLAS's kernels (OPENBLAS_CORETYPE default, Haswell, SandyBridge, Nehalem, Prescott;
// scripts/compare_sba16.py --envelope). Those twenty runs are 1.6's envelope: its iterations
// and the error it ends at move with rounding. At eps4 = 0, stop 4 is 1.6's relative-reduction
// test firing through rounding: about one accepted step in four whose relative decrease is far
// below 1e-8 ends the run, so the reason is checked to be 2 or 4, not the same one. Ours must
// end at 1.6's minimum (its error to 6 digits where the runs agree) in iterations within
// [min/1.25 - 3, 1.25 max + 3] of 1.6's. On 7camsvarK and
// 9camsvarK the valley is flat: one rejected step makes 1.6 retry on the blocks as the failed
// attempt left them, which restarts the damping high, and the run then ends by stop 4 wherever
// that happens along the valley; there the error is checked against 1.6's range, widened by
// 0.2%.
struct Sba16Run {
  DemoProblem problem;
  int min_iterations, max_iterations;
  const char *min_error, *max_error;  // equal where the runs agree
  bool flat;
};

void PrintTo(const Sba16Run &r, std::ostream *os) { *os << r.problem.name; }

class Sba16 : public ::testing::TestWithParam<Sba16Run> {};

TEST_P(Sba16, StopsByAConvergenceTestWhere16Does) {
  REQUIRE_DEMO_DATA();
  const Sba16Run &r = GetParam();
  Summary s;
  const DemoRun run = run_problem(r.problem, {});
  EXPECT_SUCCESSFUL_RUN(run, r.problem.banner, s);
  EXPECT_TRUE(s.reason == "2" || s.reason == "4") << "reason " << s.reason;
  EXPECT_GE(s.iterations(), r.min_iterations / 1.25 - 3);
  EXPECT_LE(s.iterations(), 1.25 * r.max_iterations + 3);
  if (!r.flat) {
    EXPECT_TRUE(same_to_digits(s.error, r.min_error, 6)) << s.error << " vs sba 1.6's " << r.min_error;
    return;
  }
  const double lo = std::strtod(r.min_error, nullptr), hi = std::strtod(r.max_error, nullptr);
  EXPECT_GE(s.error_value(), lo * (1 - 0.002)) << s.error;
  EXPECT_LE(s.error_value(), hi * (1 + 0.002)) << s.error;
}

INSTANTIATE_TEST_SUITE_P(Eucsbademo, Sba16,
                         ::testing::Values(Sba16Run{k7cams, 14, 18, "0.675396", "0.675396", false},
                                           Sba16Run{k9cams, 15, 20, "0.619559", "0.619559", false},
                                           Sba16Run{k54cams, 17, 22, "0.176473", "0.176473", false},
                                           Sba16Run{k7camsvarK, 52, 125, "0.659254", "0.66045", true},
                                           Sba16Run{k9camsvarK, 49, 107, "0.599938", "0.600576", true},
                                           Sba16Run{k54camsvarK, 36, 48, "0.134928", "0.134928", false},
                                           Sba16Run{k54camsvarKD, 34, 43, "0.128779", "0.128779", false}),
                         [](const ::testing::TestParamInfo<Sba16Run> &info) {
                           return std::string(info.param.problem.name);
                         });

// ---------------------------------------------------------------------------------------------
// c. The same minimum through the simple driver, the finite-difference Jacobian and the
// "motion, then motion and structure" refinement.

struct Variant {
  DemoProblem problem;
  const char *option;
  const char *error;  // the published minimum
  const char *method;
};

void PrintTo(const Variant &v, std::ostream *os) { *os << v.problem.name << " " << v.option; }

class SameMinimum : public ::testing::TestWithParam<Variant> {};

TEST_P(SameMinimum, AsThePublishedRun) {
  REQUIRE_DEMO_DATA();
  const Variant &v = GetParam();
  const DemoRun run = run_problem(v.problem, {v.option});
  Summary s;
  EXPECT_SUCCESSFUL_RUN(run, v.problem.banner, s);
  EXPECT_EQ(s.method_line, v.method);
  EXPECT_EQ(s.nvars, motstr_vars(v.problem));
  EXPECT_TRUE(converged(s)) << "reason " << s.reason;
  EXPECT_TRUE(same_to_digits(s.error, v.error, 5)) << s.error << " vs " << v.error;
}

// --numeric-jacobian with varying K: 1.6's demo holds intrinsics only by zeroing their
// analytic Jacobian columns, so its finite differences refine every intrinsic (its Method line
// still says "2 fixed"), and so does ours unless --nccalib/--ncdist is given. 54camsvarK then
// ends where 1.6's runs end, at 0.167764 after 112 to 120 iterations: forward
// differences with sba's step max(1e-4 |p|, 1e-6), about 0.1 for focal lengths around 1e3,
// stop LM above the analytic minimum (0.134928). 7camsvarK's valley is flat: see
// NumericJacobianRefinesEveryIntrinsicUnlessAsked.
const Variant kVariants[] = {
    {k7cams, "--simple", "0.675396",
     "Method BA_MOTSTRUCT, simple driver, analytic Jacobian, without covariances, without distortion, "
     "fixed intrinsics"},
    {k9cams, "--simple", "0.619559",
     "Method BA_MOTSTRUCT, simple driver, analytic Jacobian, without covariances, without distortion, "
     "fixed intrinsics"},
    {k54cams, "--simple", "0.176473",
     "Method BA_MOTSTRUCT, simple driver, analytic Jacobian, without covariances, without distortion, "
     "fixed intrinsics"},
    {k7cams, "--numeric-jacobian", "0.675396",
     "Method BA_MOTSTRUCT, expert driver, approximate Jacobian, without covariances, without distortion, "
     "fixed intrinsics"},
    {k9cams, "--numeric-jacobian", "0.619559",
     "Method BA_MOTSTRUCT, expert driver, approximate Jacobian, without covariances, without distortion, "
     "fixed intrinsics"},
    {k54cams, "--numeric-jacobian", "0.176473",
     "Method BA_MOTSTRUCT, expert driver, approximate Jacobian, without covariances, without distortion, "
     "fixed intrinsics"},
    {k54camsvarK, "--numeric-jacobian", "0.167764",
     "Method BA_MOTSTRUCT, expert driver, approximate Jacobian, without covariances, without distortion, "
     "variable intrinsics (2 fixed)"},
    // 9cams: motion alone leaves a mean squared error of 4.04939 > 4, so the demo restarts
    // with motion and structure (7cams stays below 4: see MotionThenMotStrKeepsMotionOnly).
    {k9cams, "--refine=mot-motstr", "0.619559",
     "Method BA_MOT_MOTSTRUCT, expert driver, analytic Jacobian, without covariances, without distortion, "
     "fixed intrinsics"},
};

INSTANTIATE_TEST_SUITE_P(Eucsbademo, SameMinimum, ::testing::ValuesIn(kVariants),
                         [](const ::testing::TestParamInfo<Variant> &info) {
                           std::string name = std::string(info.param.problem.name) + "_" + info.param.option;
                           std::string id;
                           for (char c : name)
                             if (std::isalnum(static_cast<unsigned char>(c))) id += c;
                             else if (c == '_') id += c;
                           return id;
                         });

// 7camsvarK with --numeric-jacobian refines every intrinsic, as 1.6's demo does (its twenty runs
// of Sba16 above end at 0.657814 to 0.658677 after 33 to 150 iterations, one of them at itmax),
// while --nccalib=2 asked for holds skew and aspect ratio (and LM runs into itmax above 0.66 in
// that model's flat valley).
TEST(Eucsbademo, NumericJacobianRefinesEveryIntrinsicUnlessAsked) {
  REQUIRE_DEMO_DATA();
  Summary all, held;
  const DemoRun run_all = run_problem(k7camsvarK, {"--numeric-jacobian"});
  EXPECT_SUCCESSFUL_RUN(run_all, kVaryingBanner, all);
  EXPECT_NE(all.method_line.find("approximate Jacobian"), std::string::npos) << all.method_line;
  EXPECT_NE(all.method_line.find("variable intrinsics (2 fixed)"), std::string::npos) << all.method_line;
  EXPECT_GE(all.error_value(), 0.657814 * (1 - 0.002));
  EXPECT_LE(all.error_value(), 0.658677 * (1 + 0.002));
  EXPECT_GE(all.iterations(), 33 / 1.25 - 3);
  const DemoRun run_held = run_problem(k7camsvarK, {"--numeric-jacobian", "--nccalib=2"});
  EXPECT_SUCCESSFUL_RUN(run_held, kVaryingBanner, held);
  EXPECT_GT(held.error_value(), 0.66);
}

// 7cams: motion only ends at a mean squared error of 3.55953 < 4 (the brief's guess that it
// exceeds 4 does not hold), so "motion, then motion and structure" keeps the motion-only result.
TEST(Eucsbademo, MotionThenMotStrKeepsMotionOnlyBelowFour) {
  REQUIRE_DEMO_DATA();
  Summary mot, both;
  const DemoRun run_mot = run_problem(k7cams, {"--refine=mot"});
  EXPECT_SUCCESSFUL_RUN(run_mot, kFixedBanner, mot);
  const DemoRun run_both = run_problem(k7cams, {"--refine=mot-motstr"});
  EXPECT_SUCCESSFUL_RUN(run_both, kFixedBanner, both);
  EXPECT_LT(mot.error_value(), 4.0);
  EXPECT_GT(mot.error_value(), 0.675396);
  EXPECT_EQ(both.error, mot.error);
  EXPECT_EQ(both.iters, mot.iters);
  EXPECT_EQ(both.nvars, 7 * 6);  // the variables of the motion-only refinement
  EXPECT_EQ(both.method_line.rfind("Method BA_MOT_MOTSTRUCT, ", 0), 0u) << both.method_line;
}

// ---------------------------------------------------------------------------------------------
// d. Motion only and structure only converge and lower the error.

struct Partial {
  DemoProblem problem;
  const char *refine;
};

void PrintTo(const Partial &p, std::ostream *os) { *os << p.problem.name << " --refine=" << p.refine; }

class PartialRefinement : public ::testing::TestWithParam<Partial> {};

TEST_P(PartialRefinement, ConvergesBelowTheInitialError) {
  REQUIRE_DEMO_DATA();
  const Partial &pr = GetParam();
  const DemoProblem &p = pr.problem;
  const bool mot = std::strcmp(pr.refine, "mot") == 0;
  const DemoRun run = run_problem(p, {std::string("--refine=") + pr.refine});
  Summary s;
  EXPECT_SUCCESSFUL_RUN(run, p.banner, s);
  EXPECT_EQ(s.method_line.rfind(mot ? "Method BA_MOT, " : "Method BA_STRUCT, ", 0), 0u) << s.method_line;
  EXPECT_EQ(s.nvars, mot ? 1LL * p.nframes * p.cnp : 3LL * p.npoints);
  EXPECT_TRUE(converged(s)) << "reason " << s.reason;
  EXPECT_LE(s.iterations(), 100);
  EXPECT_LT(s.error_value(), s.initial_value());
  // Refining a part cannot beat refining both.
  const double full = p.nframes == 7 ? 0.675396 : 0.176473;
  EXPECT_GT(s.error_value(), full);
}

INSTANTIATE_TEST_SUITE_P(Eucsbademo, PartialRefinement,
                         ::testing::Values(Partial{k7cams, "mot"}, Partial{k7cams, "str"},
                                           Partial{k54cams, "mot"}, Partial{k54cams, "str"}),
                         [](const ::testing::TestParamInfo<Partial> &info) {
                           return std::string(info.param.problem.name) + "_" + info.param.refine;
                         });

// ---------------------------------------------------------------------------------------------
// e. Round trip: the refined cameras and points, written in the input formats, read back as a
// new problem: it starts where the first run ended and has nothing left to do.

std::vector<std::vector<double>> numeric_rows(const std::string &path) {
  std::vector<std::vector<double>> rows;
  for (const std::string &line : split_lines(read_text(path))) {
    const std::size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream in(line);
    std::vector<double> row;
    for (double v; in >> v;) row.push_back(v);
    rows.push_back(row);
  }
  return rows;
}

void round_trip(const DemoProblem &p, const std::vector<std::string> &options) {
  TempDir dir;
  const std::string cams = dir.file("cams.txt"), tracks = dir.file("pts.txt"), xyz = dir.file("xyz.txt");
  std::vector<std::string> first_args = options;
  for (const std::string &a : {"--write-cams", cams.c_str(), "--write-pts-tracks", tracks.c_str(),
                               "--write-pts", xyz.c_str()})
    first_args.push_back(a);
  Summary first, second;
  const DemoRun run1 = run_problem(p, first_args);
  EXPECT_SUCCESSFUL_RUN(run1, p.banner, first);

  // The files: one camera line of the input kind per camera, one point line per point, and
  // the X Y Z file agreeing with the points file.
  const auto cam_rows = numeric_rows(cams), track_rows = numeric_rows(tracks), xyz_rows = numeric_rows(xyz);
  ASSERT_EQ(static_cast<int>(cam_rows.size()), p.nframes);
  for (const auto &row : cam_rows) {
    ASSERT_EQ(static_cast<int>(row.size()), p.cnp + 1);  // the quaternion has one more value than v
    const double *q = &row[row.size() - 7];
    EXPECT_NEAR(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], 1.0, 1e-9);
    EXPECT_GE(q[0], 0.0);
  }
  ASSERT_EQ(static_cast<int>(track_rows.size()), p.npoints);
  ASSERT_EQ(xyz_rows.size(), track_rows.size());
  for (std::size_t i = 0; i < xyz_rows.size(); ++i) {
    ASSERT_EQ(xyz_rows[i].size(), 3u);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(xyz_rows[i][c], track_rows[i][c]) << "point " << i;
  }

  std::vector<std::string> second_args = options;
  second_args.push_back(cams);
  second_args.push_back(tracks);
  if (*p.calib) second_args.push_back(demo_file(p.calib));
  const DemoRun run2 = run_demo(second_args);
  EXPECT_SUCCESSFUL_RUN(run2, p.banner, second);
  EXPECT_EQ(second.nprojs, first.nprojs);
  EXPECT_EQ(second.nvars, first.nvars);
  EXPECT_TRUE(same_to_digits(second.initial, first.error, 6))
      << "restarted at " << second.initial << ", the first run ended at " << first.error;
  EXPECT_TRUE(same_to_digits(second.error, first.error, 6)) << second.error << " vs " << first.error;
  EXPECT_TRUE(converged(second)) << "reason " << second.reason;
  // Not 0: %.10e keeps 11 significant digits, so the restart is off by ~1e-11 relative, more
  // than eps2 = 1e-12 allows, and LM takes a few tiny steps (2 to 4 measured on 7cams, 9cams,
  // 54cams; 1 on 7camsvarK).
  EXPECT_LE(second.iterations(), 5);
}

TEST(Eucsbademo, RoundTripFixedIntrinsics) {
  REQUIRE_DEMO_DATA();
  round_trip(k7cams, {});
}

// With per-camera intrinsics; --itmax 1000 so that the first run converges (it needs about 200
// iterations with chol, more than 1.6's 150).
TEST(Eucsbademo, RoundTripVaryingIntrinsics) {
  REQUIRE_DEMO_DATA();
  round_trip(k7camsvarK, {"--itmax=1000"});
}

// ---------------------------------------------------------------------------------------------
// --initial-ply and --final-ply: the points (grey) then the camera centres (red).

// The centre -R^T t of a camera line's last 7 values q0 q1 q2 q3 t1 t2 t3, with the test's own
// rotation matrix of the normalized quaternion.
std::array<double, 3> quaternion_centre(const std::vector<double> &row) {
  const double *q = &row[row.size() - 7], *t = &row[row.size() - 3];
  const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const double w = q[0] / norm, x = q[1] / norm, y = q[2] / norm, z = q[3] / norm;
  const double R[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                          {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                          {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}};
  std::array<double, 3> c{};
  for (int k = 0; k < 3; ++k) c[k] = -(R[0][k] * t[0] + R[1][k] * t[1] + R[2][k] * t[2]);
  return c;
}

// The PLY holds p's points and cameras, in grey and red, the centres those of the camera lines
// cam_rows to within tol relative to the translation's size.
void expect_ply_shape(const plytest::PlyFile &ply, const DemoProblem &p,
                      const std::vector<std::vector<double>> &cam_rows, double tol) {
  EXPECT_TRUE(ply.header_ok);
  ASSERT_EQ(ply.announced, p.npoints + p.nframes);
  ASSERT_EQ(ply.vertices.size(), static_cast<std::size_t>(ply.announced));
  for (int i = 0; i < p.npoints; ++i) EXPECT_EQ(ply.vertices[i].rgb, (std::array<int, 3>{160, 160, 160})) << i;
  ASSERT_EQ(cam_rows.size(), static_cast<std::size_t>(p.nframes));
  for (int j = 0; j < p.nframes; ++j) {
    const plytest::Vertex &v = ply.vertices[static_cast<std::size_t>(p.npoints + j)];
    EXPECT_EQ(v.rgb, (std::array<int, 3>{255, 0, 0})) << "camera " << j;
    const std::array<double, 3> c = quaternion_centre(cam_rows[j]);
    const double *t = &cam_rows[j][cam_rows[j].size() - 3];
    const double scale = std::fabs(t[0]) + std::fabs(t[1]) + std::fabs(t[2]) + 1e-300;
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(v.x[k], c[k], tol * scale) << "camera " << j << " coordinate " << k;
  }
}

// How many of the vertices [from, to) two PLY files write differently.
int moved(const plytest::PlyFile &a, const plytest::PlyFile &b, int from, int to) {
  int count = 0;
  for (int v = from; v < to; ++v) count += a.vertices.at(v).text != b.vertices.at(v).text;
  return count;
}

TEST(EucsbademoPly, InitialAndFinalPointsAndCameraCentres) {
  REQUIRE_DEMO_DATA();
  const DemoProblem &p = k7cams;
  TempDir dir;
  const std::string cams = dir.file("cams.txt"), xyz = dir.file("xyz.txt");
  const std::string initial = dir.file("i.ply"), final_ply = dir.file("f.ply");
  const DemoRun r = run_problem(p, {"--threads=1", "--write-cams", cams, "--write-pts", xyz, "--initial-ply", initial,
                                    "--final-ply", final_ply});
  Summary s, plain_summary;
  EXPECT_SUCCESSFUL_RUN(r, p.banner, s);
  // Nothing on stdout changes but the times.
  const DemoRun plain = run_problem(p, {"--threads=1"});
  EXPECT_SUCCESSFUL_RUN(plain, p.banner, plain_summary);
  const std::regex times("Elapsed time: [^\n]*|, [0-9.]+ s\\n");
  EXPECT_EQ(std::regex_replace(r.out, times, ""), std::regex_replace(plain.out, times, ""));

  const plytest::PlyFile i = plytest::read_ply(initial), f = plytest::read_ply(final_ply);
  EXPECT_EQ(i.announced, 465 + 7);
  expect_ply_shape(i, p, numeric_rows(demo_file(p.cams)), 1e-13);
  // The points as 7pts.txt gives them; camera 1's centre worked out by hand.
  const auto pts_rows = numeric_rows(demo_file(p.pts));
  for (int n = 0; n < p.npoints; ++n)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(i.vertices[n].x[k], pts_rows[n][k]) << "point " << n;
  const std::array<double, 3> kCentre1{-0.0012605960691682305, -0.0002614803816293307, -7.714635714396959e-05};
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(i.vertices[466].x[k], kCentre1[k], 1e-17) << k;

  // The final cloud is the refined cameras and points --write-cams and --write-pts wrote: the
  // points to the 11 digits of --write-pts, the centres to what 11-digit cameras allow.
  expect_ply_shape(f, p, numeric_rows(cams), 1e-9);
  const std::vector<std::string> xyz_lines = split_lines(read_text(xyz));
  ASSERT_EQ(xyz_lines.size(), static_cast<std::size_t>(p.npoints));
  for (int n = 0; n < p.npoints; ++n) {
    char line[128];
    const std::array<double, 3> &x = f.vertices[n].x;
    std::snprintf(line, sizeof line, "%.10e %.10e %.10e", x[0], x[1], x[2]);
    EXPECT_EQ(line, xyz_lines[n]) << "point " << n;
  }
  EXPECT_EQ(moved(i, f, 0, p.npoints), p.npoints);
  EXPECT_EQ(moved(i, f, p.npoints, p.npoints + p.nframes), p.nframes);
}

// Structure only: the cameras stay; motion only: the points stay. The PLY holds both.
TEST(EucsbademoPly, WhatARefinementLeavesAloneStays) {
  REQUIRE_DEMO_DATA();
  const DemoProblem &p = k7cams;
  const int all = p.npoints + p.nframes;
  for (const char *mode : {"str", "mot"}) {
    SCOPED_TRACE(mode);
    TempDir dir;
    const std::string initial = dir.file("i.ply"), final_ply = dir.file("f.ply");
    const DemoRun r = run_problem(p, {std::string("--refine=") + mode, "--threads=1", "--initial-ply", initial,
                                      "--final-ply", final_ply});
    Summary s;
    EXPECT_SUCCESSFUL_RUN(r, p.banner, s);
    const plytest::PlyFile i = plytest::read_ply(initial), f = plytest::read_ply(final_ply);
    ASSERT_EQ(i.announced, all);
    ASSERT_EQ(f.announced, all);
    const bool str = std::string(mode) == "str";
    EXPECT_EQ(moved(i, f, 0, p.npoints), str ? p.npoints : 0);
    EXPECT_EQ(moved(i, f, p.npoints, all), str ? 0 : p.nframes);
  }
}

// The centres come from the rotation and translation wherever the camera line holds them.
TEST(EucsbademoPly, CentresOfEveryCameraKind) {
  REQUIRE_DEMO_DATA();
  for (const DemoProblem *p : {&k7camsvarK, &k54camsvarKD}) {
    SCOPED_TRACE(p->name);
    TempDir dir;
    const std::string initial = dir.file("i.ply");
    const DemoRun r = run_problem(*p, {"--itmax=1", "--initial-ply", initial});
    Summary s;
    EXPECT_SUCCESSFUL_RUN(r, p->banner, s);
    const auto rows = numeric_rows(demo_file(p->cams));
    ASSERT_EQ(rows.at(0).size(), static_cast<std::size_t>(p->cnp + 1));
    expect_ply_shape(plytest::read_ply(initial), *p, rows, 1e-13);
  }
}

// ---------------------------------------------------------------------------------------------
// f. Every linear solver reaches chol's minimum.
//
// The reference minima: the published ones, and for 7camsvarK and 9camsvarK, whose valley is
// flat, chol's at --itmax 1000. On the varying-K problems the comparison runs with
// sba-clean-retry, whose retries damp the undamped blocks: with 1.6's retries (the default), a
// rejected step restarts the damping high, and stop 4 then ends the run wherever along a flat
// valley that happens, which says nothing about the solver (the default strategy's stops on
// these problems are checked against 1.6's in FlatValleysStopOnTheValleyFloor).
//
// Measured (Release, 2 threads, OpenBLAS) with --itmax 2000 and sba-clean-retry, every solver
// reaches chol's minimum on every problem; the varying-K problems are badly conditioned (focal
// lengths around 1e3 next to rotations around 1e-2), and the solvers other than chol, ldl-amd
// and sparse-chol take more iterations there:
//   7camsvarK / 9camsvarK: chol 200 / 173, ldlt 495 / 521, bk 389 / 398, lu 445 / 274,
//     qr 634 / 1025, qrnoq 802 / 787, svd 211 / 164, cg 120 / 109, ldl-amd 185 / 183,
//     sparse-chol 192 / 176 iterations (0.6..6 s each);
//   54camsvarK (1.6's itmax 150): chol 46, ldlt 79, bk 66, lu 60, qr 237 (--itmax 2000),
//     qrnoq 134, svd 49, cg 42, ldl-amd 45, sparse-chol 44 (2..50 s each).
// The slowest (54camsvarK with ldlt, qr, qrnoq, svd: about two minutes together) run only with
// SBA_LONG_TESTS=1; .ci/run sets it.

struct SolverCase {
  DemoProblem problem;
  const char *solver;
  int itmax;          // 0: the default
  const char *error;  // chol's minimum
  const char *strategy;  // null: the default
};

void PrintTo(const SolverCase &c, std::ostream *os) {
  *os << c.problem.name << " --solver=" << c.solver;
  if (c.itmax > 0) *os << " --itmax=" << c.itmax;
  if (c.strategy) *os << " --strategy=" << c.strategy;
}

enum class Tier { Default, Long };

class Solvers : public ::testing::TestWithParam<SolverCase> {
 protected:
  void check(Tier tier) {
    REQUIRE_DEMO_DATA();
    if (tier == Tier::Long && !env_flag("SBA_LONG_TESTS")) GTEST_SKIP() << "slow: set SBA_LONG_TESTS=1";
    const SolverCase &c = GetParam();
    std::vector<std::string> options{"--solver", c.solver};
    if (c.itmax > 0) options.push_back("--itmax=" + std::to_string(c.itmax));
    if (c.strategy) options.push_back(std::string("--strategy=") + c.strategy);
    const DemoRun run = run_problem(c.problem, options);
    Summary s;
    EXPECT_SUCCESSFUL_RUN(run, c.problem.banner, s);
    EXPECT_TRUE(same_to_digits(s.error, c.error, 6))
        << c.solver << " on " << c.problem.name << ": " << s.error << " after " << s.iters
        << " iterations (reason " << s.reason << "); chol reaches " << c.error;
    EXPECT_LT(s.iterations(), c.itmax > 0 ? c.itmax : 150) << "stopped by itmax";
  }
};

class SolversLong : public Solvers {};

TEST_P(Solvers, ReachCholsMinimum) { check(Tier::Default); }
TEST_P(SolversLong, ReachCholsMinimum) { check(Tier::Long); }

std::vector<SolverCase> solver_cases(const DemoProblem &p, int itmax, const char *error,
                                     const std::vector<std::string> &only = {},
                                     const std::vector<std::string> &except = {},
                                     const char *strategy = nullptr) {
  static std::vector<std::string> names;  // kept alive: SolverCase points into them
  if (names.empty()) {
    std::istringstream in(sba_linsolver_names());
    for (std::string n; in >> n;) names.push_back(n);
  }
  std::vector<SolverCase> cases;
  for (const std::string &n : names) {
    if (!only.empty() && std::find(only.begin(), only.end(), n) == only.end()) continue;
    if (std::find(except.begin(), except.end(), n) != except.end()) continue;
    cases.push_back({p, n.c_str(), itmax, error, strategy});
  }
  return cases;
}

std::vector<SolverCase> concat(std::vector<std::vector<SolverCase>> parts) {
  std::vector<SolverCase> all;
  for (auto &part : parts) all.insert(all.end(), part.begin(), part.end());
  return all;
}

constexpr int kLongItmax = 1000;
const char *const kCleanRetry = "sba-clean-retry";
const char *const k7camsvarKMinimum = "0.658995";  // chol, --itmax 1000
const char *const k9camsvarKMinimum = "0.599884";

std::string solver_case_name(const ::testing::TestParamInfo<SolverCase> &info) {
  std::string id = std::string(info.param.problem.name) + "_";
  for (const char *c = info.param.solver; *c; ++c)
    id += std::isalnum(static_cast<unsigned char>(*c)) ? *c : '_';
  return id;
}

// Default tier: about two minutes in Release on 2 threads.
INSTANTIATE_TEST_SUITE_P(
    Eucsbademo, Solvers,
    ::testing::ValuesIn(concat({
        solver_cases(k7cams, 0, "0.675396"),
        solver_cases(k9cams, 0, "0.619559"),
        solver_cases(k54cams, 0, "0.176473"),
        solver_cases(k7camsvarK, 2 * kLongItmax, k7camsvarKMinimum, {}, {}, kCleanRetry),
        solver_cases(k9camsvarK, 2 * kLongItmax, k9camsvarKMinimum, {}, {}, kCleanRetry),
        solver_cases(k54camsvarK, 0, "0.134928", {"ldl-amd", "sparse-chol", "lu", "bk", "cg", "iterative-schur"}, {},
                     kCleanRetry),
    })),
    solver_case_name);

INSTANTIATE_TEST_SUITE_P(
    Eucsbademo, SolversLong,
    ::testing::ValuesIn(concat({
        solver_cases(k54camsvarK, 0, "0.134928", {"ldlt", "qrnoq", "svd"}, {}, kCleanRetry),
        solver_cases(k54camsvarK, 2 * kLongItmax, "0.134928", {"qr"}, {}, kCleanRetry),
    })),
    solver_case_name);

// The default strategy on the flat valleys, with every solver: 1.6's retries restart the
// damping high after a rejected step, and stop 4 (eps4 = 0: a relative reduction lost in
// rounding) ends the run somewhere along the valley, never at itmax. Where depends on the
// solver and on the rounding of the BLAS's kernels and thread count, as it does for 1.6, whose
// own runs (two builds, 1 and 2 threads, seven OpenBLAS kernels) stop up to 0.22% above the
// valley's floor (the minimum the clean retries reach, k7camsvarKMinimum). Ours, over the same
// kernels and the library's portable ones, stop up to 0.42% above it (cg and iterative-schur,
// whose inexact steps end the walk sooner); the bound is 0.6%. But for svd: its pseudo-inverse
// solves the indefinite S of such a retry instead of failing, the damping is not restarted, and
// it walks down the valley as the clean retries do, into itmax on 7camsvarK.
TEST(Eucsbademo, FlatValleysStopOnTheValleyFloor) {
  REQUIRE_DEMO_DATA();
  std::istringstream in(sba_linsolver_names());
  for (std::string solver; in >> solver;)
    for (const auto &[p, floor] : {std::pair{&k7camsvarK, k7camsvarKMinimum}, std::pair{&k9camsvarK, k9camsvarKMinimum}}) {
      SCOPED_TRACE(std::string(p->name) + " --solver=" + solver);
      Summary s;
      const DemoRun run = run_problem(*p, {"--solver=" + solver});
      EXPECT_SUCCESSFUL_RUN(run, p->banner, s);
      EXPECT_TRUE(s.reason == "2" || s.reason == "4" || solver == "svd") << "reason " << s.reason;
      const double minimum = std::strtod(floor, nullptr);
      EXPECT_GE(s.error_value(), minimum * (1 - 1e-6)) << s.error;
      EXPECT_LE(s.error_value(), minimum * (1 + 0.006)) << s.error;
    }
}

// --solver against the environment: SBA_LINSOLVER still works without the option, and the option
// wins over it.
TEST(Eucsbademo, SolverOptionOverridesSbaLinsolver) {
  REQUIRE_DEMO_DATA();
  Summary by_option, by_env, both, bad_env;
  const DemoRun r1 = run_problem(k9cams, {"--solver=lu"});
  EXPECT_SUCCESSFUL_RUN(r1, kFixedBanner, by_option);
  const DemoRun r2 = run_problem(k9cams, {}, {{"SBA_LINSOLVER", "lu"}});
  EXPECT_SUCCESSFUL_RUN(r2, kFixedBanner, by_env);
  const DemoRun r3 = run_problem(k9cams, {"--solver=lu"}, {{"SBA_LINSOLVER", "no-such-solver"}});
  EXPECT_SUCCESSFUL_RUN(r3, kFixedBanner, both);  // no complaint about the variable: not used
  // The same solver gives the same steps.
  for (const Summary *s : {&by_env, &both}) {
    EXPECT_EQ(s->error, by_option.error);
    EXPECT_EQ(s->iters, by_option.iters);
    EXPECT_EQ(s->nfunc, by_option.nfunc);
    EXPECT_EQ(s->nlin, by_option.nlin);
  }
  // Without --solver the variable is read: a bad one is reported (the library falls back to chol).
  const DemoRun r4 = run_problem(k9cams, {}, {{"SBA_LINSOLVER", "no-such-solver"}});
  ASSERT_EQ(r4.status, 0) << r4;
  EXPECT_NE(r4.err.find("no-such-solver"), std::string::npos) << r4;
  bad_env = parse_summary(r4.out);
  ASSERT_TRUE(bad_env.parsed) << r4;
  EXPECT_TRUE(same_to_digits(bad_env.error, "0.619559", 6)) << bad_env.error;
}

// --strategy=trust-region reaches 1.6's published minima of the 54-camera sets in a fraction
// of the iterations (sba's strategy: 21, 39, 44); SBA_STRATEGY does the same without the
// option, and the option wins over it.
TEST(Eucsbademo, TrustRegionReachesThePublishedMinimaInFewerIterations) {
  REQUIRE_DEMO_DATA();
  struct Case {
    DemoProblem problem;
    const char *banner, *error;
    int max_iterations;
  };
  for (const Case &c : {Case{k54cams, kFixedBanner, "0.176473", 12},
                        Case{k54camsvarK, kVaryingBanner, "0.134928", 18},
                        Case{k54camsvarKD, kDistortionBanner, "0.128779", 18}}) {
    SCOPED_TRACE(c.problem.name);
    Summary tr;
    const DemoRun r = run_problem(c.problem, {"--strategy=trust-region"});
    EXPECT_SUCCESSFUL_RUN(r, c.banner, tr);
    EXPECT_EQ(tr.error, c.error);
    EXPECT_EQ(tr.reason, "4");
    EXPECT_GE(tr.iterations(), 5);
    EXPECT_LE(tr.iterations(), c.max_iterations);
  }
  Summary opt, env, both, sba;
  EXPECT_SUCCESSFUL_RUN(run_problem(k9cams, {"--strategy=trust-region"}), kFixedBanner, opt);
  EXPECT_SUCCESSFUL_RUN(run_problem(k9cams, {}, {{"SBA_STRATEGY", "trust-region"}}), kFixedBanner, env);
  EXPECT_SUCCESSFUL_RUN(run_problem(k9cams, {"--strategy=sba"}, {{"SBA_STRATEGY", "trust-region"}}),
                        kFixedBanner, both);
  EXPECT_SUCCESSFUL_RUN(run_problem(k9cams, {}), kFixedBanner, sba);
  EXPECT_EQ(env.iters, opt.iters);
  EXPECT_EQ(env.error, opt.error);
  // The option wins: 1.6's strategy, step for step.
  EXPECT_EQ(both.iters, sba.iters);
  EXPECT_EQ(both.nfunc, sba.nfunc);
  EXPECT_EQ(both.nlin, sba.nlin);
  EXPECT_EQ(both.error, sba.error);
  EXPECT_NE(both.iters, opt.iters);
  const DemoRun bad = run_problem(k9cams, {"--strategy=fast"});
  EXPECT_EQ(bad.status, 2) << bad;
  EXPECT_NE(bad.err.find("expected one of: sba sba-clean-retry trust-region"), std::string::npos) << bad;
}

// --single-precision-jacobian (the simple driver's Jacobian stored in single precision) with
// the trust region reaches the published minima of the 54-camera sets, with the Jacobian by
// differences, a robust loss and fixed cameras and points too, and the motion-only and
// structure-only minima; 1.6's strategy reaches that of the fixed-K set. With the expert driver the run fails, with the library's reason.
TEST(Eucsbademo, SinglePrecisionJacobianReachesThePublishedMinima) {
  REQUIRE_DEMO_DATA();
  struct Case {
    DemoProblem problem;
    const char *banner, *error;
    std::vector<std::string> options;
  };
  const std::vector<std::string> tr{"--simple", "--single-precision-jacobian", "--strategy=trust-region"};
  const auto with = [&tr](std::vector<std::string> more) {
    more.insert(more.begin(), tr.begin(), tr.end());
    return more;
  };
  for (const Case &c : {Case{k54cams, kFixedBanner, "0.176473", tr},
                        Case{k54camsvarK, kVaryingBanner, "0.134928", tr},
                        Case{k54camsvarKD, kDistortionBanner, "0.128779", tr},
                        Case{k54cams, kFixedBanner, "0.176473", with({"--numeric-jacobian"})},
                        Case{k54cams, kFixedBanner, "0.182322", with({"--mcon=3", "--ncon=20"})},
                        Case{k54cams, kFixedBanner, "0.176473", {"--simple", "--single-precision-jacobian"}},
                        Case{k54cams, kFixedBanner, "1.89375", with({"--refine=mot"})},
                        Case{k54cams, kFixedBanner, "0.406279", with({"--refine=str"})}}) {
    SCOPED_TRACE(c.problem.name + (" " + c.options.back()));
    Summary s;
    const DemoRun r = run_problem(c.problem, c.options);
    EXPECT_SUCCESSFUL_RUN(r, c.banner, s);
    EXPECT_EQ(s.error, c.error);
  }
  const DemoRun robust = run_problem(k54cams, with({"--loss=huber"}));
  ASSERT_EQ(robust.status, 0) << robust;
  EXPECT_NE(robust.out.find("squared error 0.178792"), std::string::npos) << robust;
  const DemoRun expert = run_problem(k54cams, {"--single-precision-jacobian"});
  EXPECT_NE(expert.status, 0) << expert;
  EXPECT_NE(expert.err.find("simple drivers"), std::string::npos) << expert;
}

// The result does not depend on the number of threads.
TEST(Eucsbademo, ThreadsDoNotChangeTheResult) {
  REQUIRE_DEMO_DATA();
  Summary one, two, three;
  const DemoRun r1 = run_problem(k9cams, {"--threads=1"});
  EXPECT_SUCCESSFUL_RUN(r1, kFixedBanner, one);
  const DemoRun r2 = run_problem(k9cams, {"--threads", "2"});
  EXPECT_SUCCESSFUL_RUN(r2, kFixedBanner, two);
  const DemoRun r3 = run_problem(k9cams, {"--threads=3", "--solver=sparse-chol"});
  EXPECT_SUCCESSFUL_RUN(r3, kFixedBanner, three);
  EXPECT_EQ(two.error, one.error);
  EXPECT_EQ(two.iters, one.iters);
  EXPECT_EQ(two.nfunc, one.nfunc);
  EXPECT_EQ(two.nlin, one.nlin);
  EXPECT_TRUE(same_to_digits(three.error, one.error, 6));
}

// The program owns its process: its solve's workers move off a core that another of its
// threads uses, unless SBA_AVOID_SHARED_CORES says otherwise, and the report says which.
// Where the threads run does not change a bit of the result.
TEST(Eucsbademo, ThreadPlacementIsTheProgramsChoiceAndLeavesTheResult) {
  REQUIRE_DEMO_DATA();
  TempDir dir;
  const std::string json = dir.file("report.json");
  // The text from "name": to the end of its value (an object's closing brace, or the next comma).
  const auto field = [](const std::string &text, const std::string &name) {
    const size_t at = text.find("\"" + name + "\": ");
    if (at == std::string::npos) return std::string("(absent)");
    const size_t value = at + name.size() + 4;
    return text.substr(at, (text[value] == '{' ? text.find('}', value) + 1 : text.find_first_of(",}", value)) - at);
  };
  std::string info;
  for (const auto &[env, on] : std::vector<std::pair<std::optional<std::string>, bool>>{
           {std::nullopt, true}, {"0", false}, {"1", true}}) {
    SCOPED_TRACE(env ? "SBA_AVOID_SHARED_CORES=" + *env : "SBA_AVOID_SHARED_CORES unset");
    Summary s;
    const DemoRun r = run_problem(k9cams, {"--threads=2", "--json=" + json}, {{"SBA_AVOID_SHARED_CORES", env}});
    EXPECT_SUCCESSFUL_RUN(r, kFixedBanner, s);
    const std::string report = read_text(json);
    EXPECT_EQ(field(report, "avoid_shared_cores"), std::string("\"avoid_shared_cores\": ") + (on ? "true" : "false"));
    EXPECT_EQ(field(report, "threads"), "\"threads\": 2");
    // Every info[] value, the errors to 17 digits, as in the first run.
    if (info.empty()) info = field(report, "info");
    EXPECT_NE(info.find("\"final_error\": 1500.57"), std::string::npos) << info;
    EXPECT_EQ(field(report, "info"), info);
  }
}

// ---------------------------------------------------------------------------------------------
// g. Bad command lines and bad files, through the executable: a non-zero status (1 for files,
// 2 for the command line), nothing on stdout, one line on stderr naming the file and line.
// The program checks everything before it prints its banner, so that line is the only one.
//
// These use small files of their own (no shared data needed): two cameras 1 unit apart looking
// down +Z at twenty points, with exact projections (4 measurements per point against 3
// parameters, so enough for the 12 camera parameters).

class BadInput : public ::testing::Test {
 protected:
  void SetUp() override {
    cams_ = dir_.write("cams.txt", "# q0 q1 q2 q3 tx ty tz\n1 0 0 0  0 0 0\n1 0 0 0  -1 0 0\n");
    calib_ = dir_.write("calib.txt", "500 0 320\n0 500 240\n0 0 1\n");
    std::ostringstream pts;
    pts << "# X Y Z nframes f x y ...\n";
    for (int i = 0; i < kPoints; ++i) {
      const double X = 0.05 * i - 0.5, Y = 0.1 * (i % 3) - 0.1, Z = 5.0 + 0.3 * (i % 4);
      char line[256];
      std::snprintf(line, sizeof line, "%.6f %.6f %.6f 2  0 %.6f %.6f  1 %.6f %.6f\n", X, Y, Z,
                    500 * X / Z + 320, 500 * Y / Z + 240, 500 * (X - 1) / Z + 320, 500 * Y / Z + 240);
      pts << line;
    }
    pts_text_ = pts.str();
    pts_ = dir_.write("pts.txt", pts_text_);
  }

  // pts.txt with line `line` (1-based) replaced.
  std::string pts_with_line(const std::string &name, int line, const std::string &text) {
    std::vector<std::string> lines = split_lines(pts_text_);
    lines.at(line - 1) = text;
    std::string all;
    for (const std::string &l : lines) all += l + "\n";
    return dir_.write(name, all);
  }

  // A failure: the status, nothing on stdout, one stderr line starting with prefix and
  // containing fragment.
  void expect_failure(const std::vector<std::string> &args, int status, const std::string &prefix,
                      const std::string &fragment = "") {
    const DemoRun r = run_demo(args);
    SCOPED_TRACE(r.err);
    EXPECT_EQ(r.status, status) << r;
    EXPECT_EQ(r.signal, 0);
    EXPECT_EQ(r.out, "");
    const std::vector<std::string> lines = r.err_lines();
    ASSERT_EQ(lines.size(), 1u) << r;
    EXPECT_EQ(lines[0].rfind(prefix, 0), 0u) << "expected to start with: " << prefix;
    EXPECT_NE(lines[0].find(fragment), std::string::npos) << "expected to contain: " << fragment;
    EXPECT_EQ(r.err.back(), '\n');
  }

  static constexpr int kPoints = 20;
  TempDir dir_;
  std::string cams_, calib_, pts_, pts_text_;
};

TEST_F(BadInput, TheGoodFilesRun) {
  const DemoRun r = run_demo({cams_, pts_, calib_});
  Summary s;
  EXPECT_SUCCESSFUL_RUN(r, kFixedBanner, s);
  EXPECT_EQ(s.npoints, kPoints);
  EXPECT_EQ(s.nframes, 2);
  EXPECT_EQ(s.nprojs, 2 * kPoints);
  EXPECT_EQ(s.nvars, 2 * 6 + kPoints * 3);
  EXPECT_LT(s.error_value(), 1e-6);  // exact projections
}

TEST_F(BadInput, MissingFile) {
  const std::string missing = dir_.file("no-such-file.txt");
  expect_failure({missing, pts_, calib_}, 1, missing + ": ", "No such file");
  expect_failure({cams_, missing, calib_}, 1, missing + ": ", "No such file");
  expect_failure({cams_, pts_, missing}, 1, missing + ": ", "No such file");
}

TEST_F(BadInput, UnreadableFile) {
  // A directory cannot be read as a file, even by root.
  const std::string d = dir_.file("a-directory");
  fs::create_directories(d);
  expect_failure({cams_, d, calib_}, 1, d + ": ");
  expect_failure({d, pts_, calib_}, 1, d + ": ");
  // A file without read permission (root reads it anyway).
  if (::geteuid() != 0) {
    const std::string locked = dir_.write("locked.txt", pts_text_);
    ::chmod(locked.c_str(), 0);
    expect_failure({cams_, locked, calib_}, 1, locked + ": ", "Permission denied");
  }
}

TEST_F(BadInput, BadOptions) {
  expect_failure({"--bogus", cams_, pts_, calib_}, 2, "eucsbademo: unknown option '--bogus'");
  expect_failure({"-x", cams_, pts_, calib_}, 2, "eucsbademo: unknown option '-x'");
  expect_failure({"--itmax=ten", cams_, pts_, calib_}, 2, "eucsbademo: bad value 'ten' for --itmax");
  expect_failure({"--threads=-1", cams_, pts_, calib_}, 2, "eucsbademo: bad value '-1' for --threads");
  expect_failure({"--threads=1000", cams_, pts_, calib_}, 2, "eucsbademo: bad value '1000' for --threads");
  expect_failure({cams_, pts_, calib_, "--solver"}, 2, "eucsbademo: option '--solver' needs a value");
  expect_failure({"--simple=1", cams_, pts_, calib_}, 2, "eucsbademo: option '--simple' takes no value");
  expect_failure({cams_}, 2, "eucsbademo: expected 2 or 3 file arguments");
  expect_failure({cams_, pts_, calib_, calib_}, 2, "eucsbademo: expected 2 or 3 file arguments");
  expect_failure({"--mcon=3", cams_, pts_, calib_}, 2, "eucsbademo: --mcon 3 is more than the 2 cameras");
}

TEST_F(BadInput, UnknownSolverListsTheKnownOnes) {
  expect_failure({"--solver=cholesky", cams_, pts_, calib_}, 2,
                 "eucsbademo: bad value 'cholesky' for --solver: expected one of: ", sba_linsolver_names());
  // Names are whole words: a prefix or a name with a blank is not one.
  expect_failure({"--solver", "cho", cams_, pts_, calib_}, 2, "eucsbademo: bad value 'cho' for --solver");
  expect_failure({"--solver", "chol ", cams_, pts_, calib_}, 2, "eucsbademo: bad value 'chol ' for --solver");
  expect_failure({"--solver=", cams_, pts_, calib_}, 2, "eucsbademo: bad value '' for --solver");
}

TEST_F(BadInput, NonNumericToken) {
  const std::string bad = pts_with_line("nonnum.txt", 3, "0.1 0.2 5.0 2  0 330 250  1 abc 250");
  expect_failure({cams_, bad, calib_}, 1, bad + ":3: ", "'abc'");
  const std::string bad_cams = dir_.write("cams_nonnum.txt", "1 0 0 0 0 0 0\n1 0 0 0 -1 O 0\n");
  expect_failure({bad_cams, pts_, calib_}, 1, bad_cams + ":2: ", "'O'");
  const std::string nan_calib = dir_.write("calib_nan.txt", "500 0 320\n0 nan 240\n0 0 1\n");
  expect_failure({cams_, pts_, nan_calib}, 1, nan_calib + ":2: ", "nan");
}

TEST_F(BadInput, NframesMismatch) {
  const std::string more = pts_with_line("more.txt", 4, "0.1 0.2 5.0 3  0 330 250  1 230 250");
  expect_failure({cams_, more, calib_}, 1, more + ":4: ", "nframes");
  const std::string fewer = pts_with_line("fewer.txt", 3, "0.1 0.2 5.0 1  0 330 250  1 230");
  expect_failure({cams_, fewer, calib_}, 1, fewer + ":3: ", "nframes");
  // 1 frame and 6 values reads as a frame with the upper triangle of its covariance: refused as
  // a change of covariance form (the first point has none); on the first point it would set
  // the form and fail as a covariance that is not positive definite.
  const std::string ambiguous = pts_with_line("ambiguous.txt", 3, "0.1 0.2 5.0 1  0 330 250  1 230 250");
  expect_failure({cams_, ambiguous, calib_}, 1, ambiguous + ":3: ", "covariance");
}

TEST_F(BadInput, EmptyPointsFile) {
  const std::string empty = dir_.write("empty.txt", "");
  expect_failure({cams_, empty, calib_}, 1, empty + ":", "no points");
  const std::string comments = dir_.write("comments.txt", "# X Y Z nframes ...\n\n# nothing\n");
  expect_failure({cams_, comments, calib_}, 1, comments + ":", "no points");
}

TEST_F(BadInput, FrameIndexOutOfRange) {
  const std::string high = pts_with_line("high.txt", 5, "0.1 0.2 5.0 2  0 330 250  2 230 250");
  expect_failure({cams_, high, calib_}, 1, high + ":5: ", "frame index 2");
  const std::string negative = pts_with_line("negative.txt", 5, "0.1 0.2 5.0 2  -1 330 250  1 230 250");
  expect_failure({cams_, negative, calib_}, 1, negative + ":5: ", "frame index -1");
  const std::string twice = pts_with_line("twice.txt", 6, "0.1 0.2 5.0 2  1 330 250  1 230 250");
  expect_failure({cams_, twice, calib_}, 1, twice + ":6: ");
}

TEST_F(BadInput, BadCameraAndCalibrationFiles) {
  const std::string short_line = dir_.write("cams_short.txt", "1 0 0 0 0 0 0\n1 0 0 0 -1 0\n");
  expect_failure({short_line, pts_, calib_}, 1, short_line + ":2: ");
  const std::string six = dir_.write("cams_six.txt", "1 0 0 0 0 0\n1 0 0 0 -1 0\n");
  expect_failure({six, pts_, calib_}, 1, six + ":1: ");
  const std::string two_rows = dir_.write("calib_2rows.txt", "500 0 320\n0 500 240\n");
  expect_failure({cams_, pts_, two_rows}, 1, two_rows + ":");
  // A calibration file with per-camera intrinsics does not apply.
  const std::string var_k = dir_.write("cams_vark.txt",
                                       "500 320 240 1 0  1 0 0 0  0 0 0\n500 320 240 1 0  1 0 0 0  -1 0 0\n");
  expect_failure({var_k, pts_, calib_}, 1, var_k + ":1: ");
}

// When the library refuses the problem (here too few measurements: 4 points, 16 measurements
// for 6 + 6 + 12 parameters) the run fails: the banner, the library's reason, the demo's line,
// status 1 and nothing on stdout.
TEST_F(BadInput, SolverFailureIsNotSuccess) {
  std::string few;
  for (int line = 1; line <= 5; ++line) few += split_lines(pts_text_)[line - 1] + "\n";
  const std::string pts = dir_.write("few.txt", few);
  const DemoRun r = run_demo({cams_, pts, calib_});
  EXPECT_EQ(r.status, 1) << r;
  EXPECT_EQ(r.out, "");
  const std::vector<std::string> lines = r.err_lines();
  ASSERT_GE(lines.size(), 2u) << r;
  EXPECT_EQ(lines.front(), kFixedBanner);
  EXPECT_EQ(lines.back(), "eucsbademo: sba_motstr_levmar_x_ext failed (SBA_ERROR): no result");
}

TEST_F(BadInput, UnwritableOutputIsReportedBeforeSolving) {
  const std::string nowhere = dir_.file("no-such-dir/cams.txt");
  expect_failure({"--write-cams", nowhere, cams_, pts_, calib_}, 1, nowhere + ": ",
                 "cannot open for writing");
}

// ---------------------------------------------------------------------------------------------
// Output that does not get where it should: a failure, never half a result.

TEST_F(BadInput, StdoutWriteErrorIsAFailure) {
  ChildSetup full;
  full.stdout_to = "/dev/full";
  DemoRun r = run_demo({cams_, pts_, calib_}, {}, full);
  EXPECT_EQ(r.status, 1) << r;
  EXPECT_EQ(r.err, std::string(kFixedBanner) + "\neucsbademo: error writing standard output: No space left on device\n");
  r = run_demo({"--help"}, {}, full);
  EXPECT_EQ(r.status, 1) << r;
  EXPECT_EQ(r.err, "eucsbademo: error writing standard output: No space left on device\n");
}

bool has_temporary(const std::string &dir) {
  for (const auto &e : fs::directory_iterator(dir))
    if (e.path().filename().string().find(".tmp.") != std::string::npos) return true;
  return false;
}

std::vector<std::string> file_names(const std::string &dir) {
  std::vector<std::string> names;
  for (const auto &e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// A write cut short (by the file size limit, which root meets as it would a full disk): the run
// fails, an existing file keeps its content, and no temporary is left beside it.
TEST_F(BadInput, FailedWriteLeavesTheOldFileAndNoTemporary) {
  const std::string out_dir = dir_.file("out");
  fs::create_directories(out_dir);
  const std::string target = out_dir + "/old.txt";
  // Each of these files has about 1000 bytes or more; stderr's two lines stay under the limit.
  ChildSetup small;
  small.file_size = 512;
  for (const char *option : {"--write-pts=", "--write-pts-tracks=", "--write-stddev="}) {
    SCOPED_TRACE(option);
    std::ofstream(target) << "OLD\n";
    const DemoRun r = run_demo({option + target, cams_, pts_, calib_}, {}, small);
    EXPECT_EQ(r.status, 1) << r;
    EXPECT_EQ(r.out, "");
    EXPECT_EQ(r.err, std::string(kFixedBanner) + "\n" + target + ": write failed: File too large\n");
    const std::string after = read_text(target);
    EXPECT_TRUE(after == "OLD\n") << "the old file now starts with: " << after.substr(0, 60);
    EXPECT_FALSE(has_temporary(out_dir));
  }
}

// A run whose last file cannot be written (on a full disk: /dev/full here) leaves no new file
// and every old one as it was, whether the failing file is a result, the standard deviations,
// a PLY file or the JSON report written after the summary.
TEST_F(BadInput, FailedRunLeavesNoNewFileAndOldFilesAsTheyWere) {
  const std::string out_dir = dir_.file("out");
  fs::create_directories(out_dir);
  const std::string old = out_dir + "/old.txt", fresh = out_dir + "/new.txt", ply = out_dir + "/i.ply";
  const std::vector<std::string> kFailing{"--write-pts=/dev/full", "--write-stddev=/dev/full", "--final-ply=/dev/full",
                                          "--json=/dev/full"};
  for (const std::string &failing : kFailing) {
    SCOPED_TRACE(failing);
    for (const std::string &name : file_names(out_dir)) fs::remove(out_dir + "/" + name);
    std::ofstream(old) << "OLD\n";
    const DemoRun r = run_demo({"--write-cams=" + fresh, "--write-pts-tracks=" + old, "--initial-ply=" + ply, failing,
                                cams_, pts_, calib_});
    EXPECT_EQ(r.status, 1) << r;
    EXPECT_EQ(r.err, std::string(kFixedBanner) + "\n/dev/full: write failed: No space left on device\n");
    EXPECT_EQ(file_names(out_dir), std::vector<std::string>{"old.txt"});
    const std::string after = read_text(old);
    EXPECT_TRUE(after == "OLD\n") << "the old file now starts with: " << after.substr(0, 60);
  }
}

// Successful writes replace old files whole (keeping their permissions) and leave no
// temporary; /dev/null is written to, not replaced.
TEST_F(BadInput, WritesReplaceOldFilesAndLeaveNoTemporary) {
  const std::string out_dir = dir_.file("out");
  fs::create_directories(out_dir);
  const std::vector<std::string> names{"cams.txt", "pts.txt", "sd.txt", "tracks.txt"};
  for (const std::string &name : names) std::ofstream(out_dir + "/" + name) << "OLD\n";
  ASSERT_EQ(::chmod((out_dir + "/cams.txt").c_str(), 0640), 0);
  const DemoRun r = run_demo({"--write-cams=" + out_dir + "/cams.txt", "--write-pts=" + out_dir + "/pts.txt",
                              "--write-pts-tracks=" + out_dir + "/tracks.txt", "--write-stddev=" + out_dir + "/sd.txt",
                              cams_, pts_, calib_});
  Summary s;
  EXPECT_SUCCESSFUL_RUN(r, kFixedBanner, s);
  EXPECT_EQ(file_names(out_dir), names);
  EXPECT_EQ(split_lines(read_text(out_dir + "/cams.txt")).size(), 3u);
  EXPECT_EQ(split_lines(read_text(out_dir + "/pts.txt")).size(), size_t(kPoints));
  EXPECT_EQ(split_lines(read_text(out_dir + "/tracks.txt")).size(), size_t(kPoints) + 1);
  EXPECT_EQ(split_lines(read_text(out_dir + "/sd.txt")).size(), size_t(kPoints) + 2 + 2);
  struct stat st {};
  ASSERT_EQ(::stat((out_dir + "/cams.txt").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0640u);

  const DemoRun null_run = run_demo({"--write-cams=/dev/null", cams_, pts_, calib_});
  EXPECT_SUCCESSFUL_RUN(null_run, kFixedBanner, s);
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
}

// A FIFO as output: written to once, as its reader expects. Checking it beforehand must
// neither block (opening it to read waits for a writer) nor end the reader's stream.
TEST_F(BadInput, WritesToAFifo) {
  const std::string fifo = dir_.file("fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] { received = read_text(fifo); });
  ChildSetup limited;
  limited.alarm_seconds = 10;
  const DemoRun r = run_demo({"--write-pts=" + fifo, cams_, pts_, calib_}, {}, limited);
  // If the reader still waits for a writer (the run failed), an empty stream lets it finish.
  const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
  if (fd >= 0) ::close(fd);
  reader.join();
  Summary s;
  EXPECT_SUCCESSFUL_RUN(r, kFixedBanner, s);
  EXPECT_EQ(split_lines(received).size(), size_t(kPoints));
}

// ---------------------------------------------------------------------------------------------
// Files without line breaks: each reader reads at most one line's limit of them.

// /dev/zero in each file's place: refused at once with the line limit, under a limit of
// 512 MiB of address space that reading the whole line first would exceed.
TEST_F(BadInput, DevZeroIsRefusedAtTheLineLimit) {
  ChildSetup limited;
  limited.address_space = rlim_t(512) << 20;
  for (int k = 0; k < 3; ++k) {
    std::vector<std::string> args{cams_, pts_, calib_};
    args[size_t(k)] = "/dev/zero";
    const DemoRun r = run_demo(args, {}, limited);
    EXPECT_EQ(r.status, 1) << r;
    EXPECT_EQ(r.out, "");
    // The points file's limit scales with the cameras, and is 1 MiB for 2.
    EXPECT_EQ(r.err, "/dev/zero:1: line longer than 1048576 bytes\n") << "argument " << k;
  }
}

// The points file's limit grows with the cameras: a point seen by 40,000 cameras makes a
// line of more than 1 MiB, which is read; one byte past the limit is not.
TEST(EucsbaReaders, LineLimitScalesWithTheCameras) {
  TempDir dir;
  std::string line = "0 0 5 40000";
  for (int j = 0; j < 40000; ++j) line += " " + std::to_string(j) + " 320.0000000001 240.0000000001";
  ASSERT_GT(line.size(), size_t(1) << 20);
  const std::string wide = dir.write("wide.txt", "# X Y Z nframes ...\n" + line + "\n");
  eucsba::PointSet points;
  std::string error;
  ASSERT_TRUE(eucsba::read_points(wide, 40000, &points, &error)) << error;
  EXPECT_EQ(points.nprojections(), 40000);

  // With 2 cameras the limit is 1 MiB, a comment line included.
  const std::string at_limit = dir.write("at.txt", "#" + std::string((1 << 20) - 1, 'x') + "\n0 0 5 1  0 320 240\n");
  EXPECT_TRUE(eucsba::read_points(at_limit, 2, &points, &error)) << error;
  const std::string beyond = dir.write("beyond.txt", "0 0 5 1  0 320 240\n#" + std::string(1 << 20, 'x') + "\n");
  EXPECT_FALSE(eucsba::read_points(beyond, 2, &points, &error));
  EXPECT_EQ(error, beyond + ":2: line longer than 1048576 bytes");
  // 40,000 cameras: (4 + 7 * 40000) * 64 bytes.
  const std::string beyond_wide = dir.write("beyond-wide.txt", std::string(size_t(280004) * 64 + 1, ' ') + "\n");
  EXPECT_FALSE(eucsba::read_points(beyond_wide, 40000, &points, &error));
  EXPECT_EQ(error, beyond_wide + ":1: line longer than 17920256 bytes");
  eucsba::CameraFile cams;
  EXPECT_FALSE(eucsba::read_cameras(beyond, &cams, &error));
  EXPECT_EQ(error, beyond + ":2: line longer than 1048576 bytes");
}

TEST(Eucsbademo, HelpListsSolverAndThreads) {
  const DemoRun r = run_demo({"--help"});
  ASSERT_EQ(r.status, 0) << r;
  EXPECT_EQ(r.err, "");
  EXPECT_NE(r.out.find("--solver=NAME"), std::string::npos);
  EXPECT_NE(r.out.find("--threads=N"), std::string::npos);
  EXPECT_NE(r.out.find("SBA_LINSOLVER"), std::string::npos);
  EXPECT_NE(r.out.find(std::string("Linear solvers (--solver): ") + sba_linsolver_names()),
            std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// Beyond 1.6: a robust loss, the standard deviations of the solution, no progress line unless
// stderr is a terminal.

TEST(Eucsbademo, RobustLossAddsALineAndKeepsThe16Lines) {
  REQUIRE_DEMO_DATA();
  const DemoRun r = run_problem(k7cams, {"--loss=huber", "--loss-scale=1"});
  // The six lines of 1.6, then one more, then the report.
  const std::vector<std::string> lines = r.out_lines();
  ASSERT_GE(lines.size(), 4u) << r.out;
  const std::string robust = lines[lines.size() - 4];
  DemoRun without_robust = r;
  const std::size_t at = r.out.find(robust + "\n");
  ASSERT_NE(at, std::string::npos);
  without_robust.out.erase(at, robust.size() + 1);
  Summary s;
  EXPECT_SUCCESSFUL_RUN(without_robust, kFixedBanner, s);
  // The robust cost is below the squared error, and the squared error of the Huber fit is
  // above least squares' 0.675396 (it trades squared error for robustness).
  double cost = std::stod(s.error), sq = 0, sq0 = 0;
  long long beyond = -1;
  ASSERT_EQ(std::sscanf(robust.c_str(),
                        "Robust loss huber (scale 1): the errors above are its cost; squared error %lf "
                        "[initial %lf], %lld projections beyond the scale",
                        &sq, &sq0, &beyond),
            3)
      << robust;
  EXPECT_LT(cost, sq);
  EXPECT_GT(sq, 0.675396);
  EXPECT_NEAR(sq0, 19.0947, 1e-4);
  EXPECT_GT(beyond, 0);
  EXPECT_LT(beyond, 1916 / 5);
  EXPECT_EQ(r.err.find('\r'), std::string::npos) << "no progress line on a pipe";
}

TEST(Eucsbademo, WritesStandardDeviationsOfTheSolution) {
  REQUIRE_DEMO_DATA();
  TempDir dir;
  const std::string sd = dir.file("sd.txt");
  const DemoRun r = run_problem(k7cams, {"--mcon=2", "--write-stddev=" + sd});
  Summary s;
  EXPECT_SUCCESSFUL_RUN(r, kFixedBanner, s);
  std::istringstream in(read_text(sd));
  std::string line;
  std::vector<std::vector<double>> rows;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::vector<double> v;
    for (double d; ls >> d;) v.push_back(d);
    rows.push_back(v);
  }
  ASSERT_EQ(rows.size(), 7u + 465u);
  for (int j = 0; j < 7; ++j) {
    ASSERT_EQ(rows[size_t(j)].size(), 6u);
    for (double v : rows[size_t(j)]) {
      if (j < 2) EXPECT_EQ(v, 0.0) << "camera " << j << " is fixed";
      else EXPECT_GT(v, 0.0) << "camera " << j;
    }
  }
  for (size_t i = 7; i < rows.size(); ++i) {
    ASSERT_EQ(rows[i].size(), 3u);
    for (double v : rows[i]) EXPECT_GT(v, 0.0);
  }
  // Mean squared error 0.675 per projection: sigma of a coordinate is about 0.6 pixel; points
  // 1e-2 away at 850 pixels focal length move by about sigma / f * depth: well under 1e-3.
  EXPECT_LT(rows[7][2], 1e-3);
}

// The library refuses the covariance of a point seen by one camera only (its 3 coordinates
// are not determined by 2 measurements): the run fails with the library's line naming the
// point and the demo's own, and writes none of the files asked for.
TEST(Eucsbademo, StddevRefusedForAPointSeenOnceWritesNoFile) {
  REQUIRE_DEMO_DATA();
  TempDir dir;
  const std::string pts = dir.write("7pts+1.txt", read_text(demo_file("7pts.txt")) + "0.1 0.2 5.0 1  3 100.0 200.0\n");
  const std::string sd = dir.file("sd.txt"), cams = dir.file("cams.txt");
  const DemoRun r = run_demo({"--write-stddev=" + sd, "--write-cams=" + cams, demo_file(k7cams.cams), pts,
                              demo_file(k7cams.calib)});
  EXPECT_EQ(r.status, 1) << r;
  EXPECT_EQ(r.out, "");
  const std::vector<std::string> lines = r.err_lines();
  ASSERT_EQ(lines.size(), 3u) << r;
  EXPECT_EQ(lines[0], kFixedBanner);
  EXPECT_EQ(lines[1].rfind("sba: point 465 is seen by one camera only", 0), 0u) << lines[1];
  EXPECT_EQ(lines[2], sd + ": the covariance of the solution could not be computed: no file written");
  EXPECT_FALSE(fs::exists(sd));
  EXPECT_FALSE(fs::exists(cams));
}

// ---------------------------------------------------------------------------------------------
// h. The option parser itself.

struct Parsed {
  bool ok = false;
  eucsbademo::DemoOptions options;
  std::string error;
};

Parsed parse(std::vector<std::string> args) {
  args.insert(args.begin(), "eucsbademo");
  std::vector<const char *> argv;
  for (const std::string &a : args) argv.push_back(a.c_str());
  Parsed p;
  p.ok = eucsbademo::parse_command_line(static_cast<int>(argv.size()), argv.data(), &p.options, &p.error);
  return p;
}

TEST(DemoOptions, DefaultsAreSba16s) {
  const Parsed p = parse({"c.txt", "p.txt", "k.txt"});
  ASSERT_TRUE(p.ok) << p.error;
  const eucsbademo::DemoOptions &o = p.options;
  EXPECT_EQ(o.refine, eucsbademo::RefineMode::MotionStructure);
  EXPECT_TRUE(o.expert);
  EXPECT_TRUE(o.analytic);
  EXPECT_EQ(o.itmax, -1);
  EXPECT_EQ(o.opts, (std::array<double, 5>{1e-3, 1e-12, 1e-12, 1e-12, 0.0}));
  EXPECT_EQ(o.verbose, 0);
  EXPECT_EQ(o.mcon, 0);
  EXPECT_EQ(o.ncon, 0);
  EXPECT_EQ(o.nccalib, 2);
  EXPECT_EQ(o.ncdist, 3);
  EXPECT_FALSE(o.check_jacobian);
  EXPECT_EQ(o.linsolver, "");  // the library's choice: SBA_LINSOLVER, else chol
  EXPECT_EQ(o.nthreads, 0);
  EXPECT_EQ(o.files, (std::vector<std::string>{"c.txt", "p.txt", "k.txt"}));
  EXPECT_FALSE(o.help);
  EXPECT_FALSE(o.version);
}

TEST(DemoOptions, EverySolverNameIsAccepted) {
  std::istringstream names(sba_linsolver_names());
  int count = 0;
  for (std::string name; names >> name; ++count) {
    EXPECT_NE(sba_linsolver_valid(name.c_str()), 0) << name;
    Parsed p = parse({"--solver", name, "c", "p"});
    ASSERT_TRUE(p.ok) << p.error;
    EXPECT_EQ(p.options.linsolver, name);
    p = parse({"--solver=" + name, "c", "p"});
    ASSERT_TRUE(p.ok) << p.error;
    EXPECT_EQ(p.options.linsolver, name);
  }
  EXPECT_GE(count, 10);
  for (const char *bad : {"", "CHOL", "cho", "chol ", " chol", "ldl", "sparse", "chol ldlt"})
    EXPECT_EQ(sba_linsolver_valid(bad), 0) << "'" << bad << "'";
}

TEST(DemoOptions, UnknownSolver) {
  const Parsed p = parse({"--solver=magic", "c", "p"});
  ASSERT_FALSE(p.ok);
  EXPECT_EQ(p.error,
            std::string("bad value 'magic' for --solver: expected one of: ") + sba_linsolver_names());
  EXPECT_EQ(p.error.find('\n'), std::string::npos);
}

TEST(DemoOptions, Threads) {
  Parsed p = parse({"--threads", "4", "c", "p"});
  ASSERT_TRUE(p.ok) << p.error;
  EXPECT_EQ(p.options.nthreads, 4);
  p = parse({"--threads=0", "c", "p"});
  ASSERT_TRUE(p.ok) << p.error;
  EXPECT_EQ(p.options.nthreads, 0);
  p = parse({"--threads=" + std::to_string(eucsbademo::kMaxThreads), "c", "p"});
  ASSERT_TRUE(p.ok) << p.error;
  EXPECT_EQ(p.options.nthreads, eucsbademo::kMaxThreads);
  for (const std::string &bad : std::vector<std::string>{"-1", "x", "", "2.5", "1e3",
                                                        std::to_string(eucsbademo::kMaxThreads + 1),
                                                        "99999999999999999999"}) {
    p = parse({"--threads=" + bad, "c", "p"});
    EXPECT_FALSE(p.ok) << "'" << bad << "'";
    EXPECT_EQ(p.error.rfind("bad value '" + bad + "' for --threads: expected an integer from 0 to", 0), 0u)
        << p.error;
  }
}

TEST(DemoOptions, OtherOptions) {
  const Parsed p = parse({"--refine=mot-motstr", "--simple", "--numeric-jacobian", "--itmax", "7",
                          "--opts=1e-2,1e-10,1e-9,1e-8,1e-3", "--verbose=1", "--mcon=1", "--ncon=2",
                          "--nccalib=5", "--ncdist=0", "--write-cams=a", "--write-pts", "b",
                          "--write-pts-tracks=c", "--", "--cams", "pts"});
  ASSERT_TRUE(p.ok) << p.error;
  const eucsbademo::DemoOptions &o = p.options;
  EXPECT_EQ(o.refine, eucsbademo::RefineMode::MotionThenMotionStructure);
  EXPECT_FALSE(o.expert);
  EXPECT_FALSE(o.analytic);
  EXPECT_EQ(o.itmax, 7);
  EXPECT_EQ(o.opts, (std::array<double, 5>{1e-2, 1e-10, 1e-9, 1e-8, 1e-3}));
  EXPECT_EQ(o.verbose, 1);
  EXPECT_EQ(o.mcon, 1);
  EXPECT_EQ(o.ncon, 2);
  EXPECT_EQ(o.nccalib, 5);
  EXPECT_EQ(o.ncdist, 0);
  EXPECT_EQ(o.write_cams, "a");
  EXPECT_EQ(o.write_pts, "b");
  EXPECT_EQ(o.write_pts_tracks, "c");
  EXPECT_EQ(o.files, (std::vector<std::string>{"--cams", "pts"}));  // after "--": files
  // The last of --simple / --expert wins.
  EXPECT_TRUE(parse({"--simple", "--expert", "c", "p"}).options.expert);
  EXPECT_EQ(parse({"--tau=0.5", "--eps4=1e-6", "c", "p"}).options.opts,
            (std::array<double, 5>{0.5, 1e-12, 1e-12, 1e-12, 1e-6}));
}

TEST(DemoOptions, Errors) {
  struct Case {
    std::vector<std::string> args;
    std::string error;
  };
  const Case cases[] = {
      {{"--nope", "c", "p"}, "unknown option '--nope' (see --help)"},
      {{"-v", "c", "p"}, "unknown option '-v' (options are long: see --help)"},
      {{"c", "p", "--itmax"}, "option '--itmax' needs a value (N)"},
      {{"--help=yes"}, "option '--help' takes no value"},
      {{"--refine=all", "c", "p"}, "bad value 'all' for --refine: expected one of: motstr, mot, str, mot-motstr"},
      {{"--itmax=-1", "c", "p"}, "bad value '-1' for --itmax: expected an integer >= 0"},
      {{"--nccalib=6", "c", "p"}, "bad value '6' for --nccalib: expected an integer from 0 to 5"},
      {{"--tau=0", "c", "p"}, "bad value '0' for --tau: expected a positive number"},
      {{"--eps1=-1", "c", "p"}, "bad value '-1' for --eps1: expected a non-negative number"},
      {{"--opts=1,2,3,4", "c", "p"}, "bad value '1,2,3,4' for --opts: expected 5 comma-separated numbers"},
      {{"--opts=1,2,x,4,5", "c", "p"},
       "bad value '1,2,x,4,5' for --opts: number 3: expected a non-negative number"},
      {{"--write-cams=", "c", "p"}, "bad value '' for --write-cams: expected a file name"},
      {{"c"}, "expected 2 or 3 file arguments (cams.txt pts.txt [calib.txt]), got 1 (see --help)"},
      {{"a", "b", "c", "d"},
       "expected 2 or 3 file arguments (cams.txt pts.txt [calib.txt]), got 4 (see --help)"},
      {{"--check-jacobian", "--numeric-jacobian", "c", "p"},
       "--check-jacobian checks the analytic Jacobian: it cannot go with --numeric-jacobian"},
  };
  for (const Case &c : cases) {
    const Parsed p = parse(c.args);
    EXPECT_FALSE(p.ok) << c.error;
    EXPECT_EQ(p.error, c.error);
  }
}

TEST(DemoOptions, HelpAndVersionNeedNoFiles) {
  Parsed p = parse({"--help"});
  ASSERT_TRUE(p.ok) << p.error;
  EXPECT_TRUE(p.options.help);
  p = parse({"-h"});
  ASSERT_TRUE(p.ok) << p.error;
  EXPECT_TRUE(p.options.help);
  p = parse({"--version"});
  ASSERT_TRUE(p.ok) << p.error;
  EXPECT_TRUE(p.options.version);
}

TEST(DemoOptions, UsageDocumentsEveryOption) {
  char *buf = nullptr;
  std::size_t len = 0;
  std::FILE *f = ::open_memstream(&buf, &len);
  ASSERT_NE(f, nullptr);
  eucsbademo::print_usage(f);
  std::fclose(f);
  const std::string text(buf, len);
  std::free(buf);
  for (const char *opt :
       {"--refine=MODE", "--simple", "--expert", "--numeric-jacobian", "--itmax=N", "--opts=", "--tau=X",
        "--eps1=X", "--eps4=X", "--verbose=N", "--mcon=N", "--ncon=N", "--nccalib=N", "--ncdist=N",
        "--solver=NAME", "--threads=N", "--check-jacobian", "--write-cams=FILE", "--write-pts=FILE",
        "--write-pts-tracks=FILE", "--initial-ply=FILE", "--final-ply=FILE", "--help", "--version"})
    EXPECT_NE(text.find(opt), std::string::npos) << opt;
  EXPECT_NE(text.find(sba_linsolver_names()), std::string::npos);
  EXPECT_NE(text.find("SBA_NUM_THREADS"), std::string::npos);
}

}  // namespace
