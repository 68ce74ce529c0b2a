// SPDX-License-Identifier: BSD-3-Clause
// Stopping eucsbademo and balsba mid-solve (demo/cli/run_control.h): SIGINT or SIGTERM sent to the
// running program, a second signal, and --max-time. The programs run as child processes; a
// signal is sent once the solve has started, on problems that take several seconds, so that
// it arrives in the middle of an iteration.
//
// What a stopped run must do: print the summary with stop reason 9, write the results it was
// asked for, and those results must be the last accepted estimate: the same bytes as an
// uninterrupted run with itmax set to the iterations the stopped run made (one thread, so the
// two runs round alike).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "scratch.h"

namespace {

std::string slurp(const std::string &path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

bool exists(const std::string &path) { return access(path.c_str(), F_OK) == 0; }

struct ChildRun {
  int exit_status = -1;  // -1: not a normal exit
  std::string out, err;
};

// Starts exe with args, stdout and stderr to files; calls act(pid, err_path) while it runs,
// then waits for it. ignoring: a signal the program is started with ignored (0: none).
template <class Act>
ChildRun run_child(const std::string &exe, const std::vector<std::string> &args, const std::string &base, Act act,
                   int ignoring = 0) {
  const std::string out = base + ".out", err = base + ".err";
  std::remove(out.c_str());
  std::remove(err.c_str());
  const pid_t pid = fork();
  if (pid == 0) {
    if (!std::freopen(out.c_str(), "w", stdout) || !std::freopen(err.c_str(), "w", stderr)) _exit(127);
    if (ignoring != 0) signal(ignoring, SIG_IGN);  // kept across exec
    std::vector<char *> argv{const_cast<char *>(exe.c_str())};
    for (const std::string &a : args) argv.push_back(const_cast<char *>(a.c_str()));
    argv.push_back(nullptr);
    execv(exe.c_str(), argv.data());
    _exit(127);
  }
  ChildRun r;
  if (pid < 0) return r;
  act(pid, err);
  int status = 0;
  waitpid(pid, &status, 0);
  r.exit_status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

// Waits until path holds text (the program's announcement that the solve starts), at most 60 s.
bool wait_for(const std::string &path, const std::string &text) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < deadline) {
    if (slurp(path).find(text) != std::string::npos) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

// Waits until signal sig sent to pid is no longer pending (/proc/PID/status: SigPnd, ShdPnd),
// i.e. the process has taken it, at most 10 s. Polled without sleeping: a second signal sent
// right after must reach the program before anything else happens there (a sleep would leave
// room for an iteration to end, and two signals both still pending would merge into one).
bool wait_delivered(pid_t pid, int sig) {
  const unsigned long long bit = 1ull << (sig - 1);
  const std::string path = "/proc/" + std::to_string(pid) + "/status";
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (std::chrono::steady_clock::now() < deadline) {
    std::ifstream in(path);
    std::string line;
    bool pending = false;
    while (std::getline(in, line))
      if (line.rfind("SigPnd:", 0) == 0 || line.rfind("ShdPnd:", 0) == 0)
        pending = pending || (std::stoull(line.substr(7), nullptr, 16) & bit) != 0;
    if (!pending) return true;
  }
  return false;
}

// The iterations of "SBA returned N in N iter, reason R, ..."; -1 if absent.
int iterations(const std::string &out, int *reason) {
  std::smatch m;
  static const std::regex re("SBA returned (-?[0-9]+) in ([0-9]+) iter, reason ([0-9]+),");
  if (!std::regex_search(out, m, re)) return -1;
  *reason = std::stoi(m[3]);
  return std::stoi(m[2]);
}

// The iterations of a run that a signal stopped: it exited with 128 + sig and printed its
// summary with stop reason 9. -1, the failure recorded, if not.
int stopped_after(const ChildRun &r, int sig) {
  EXPECT_EQ(r.exit_status, 128 + sig) << r.err;
  int reason = 0;
  const int n = iterations(r.out, &reason);
  EXPECT_GE(n, 1) << r.out;
  EXPECT_EQ(reason, 9) << r.out;
  return n;
}

class EucsbademoStop : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = sbatest::scratch_dir() + "test_interrupt." + std::to_string(getpid()) + "/";
    ASSERT_EQ(std::system(("mkdir -p " + dir_).c_str()), 0);
    // 120 cameras, 12,000 points: with the SVD solver on one thread each iteration takes a
    // good fraction of a second, and the whole solve several seconds.
    const std::string cmd = std::string(SBAGEN_EXE) + " --quiet --out " + dir_ +
                            "big --cameras 120 --points 12000 --perturb-rotation 0.03 --perturb-points 0.05 "
                            "--seed 3";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  }
  static std::vector<std::string> args(const std::vector<std::string> &extra) {
    std::vector<std::string> a{"--solver=svd", "--threads=1", "--no-progress"};
    a.insert(a.end(), extra.begin(), extra.end());
    for (const char *f : {"big-cams.txt", "big-pts.txt", "big-calib.txt"}) a.push_back(dir_ + f);
    return a;
  }
  static std::string dir_;
};
std::string EucsbademoStop::dir_;

TEST_F(EucsbademoStop, SignalStopsAtTheEndOfAnIterationWithTheLastAcceptedEstimate) {
  for (int sig : {SIGINT, SIGTERM}) {
    const std::string cams = dir_ + "stopped-cams.txt", pts = dir_ + "stopped-pts.txt", ply = dir_ + "stopped.ply";
    const ChildRun r = run_child(EUCSBADEMO_EXE, args({"--write-cams=" + cams, "--write-pts", pts, "--final-ply", ply}),
                                 dir_ + "run",
                            [sig](pid_t pid, const std::string &err) {
                              ASSERT_TRUE(wait_for(err, "Starting BA"));
                              std::this_thread::sleep_for(std::chrono::milliseconds(800));
                              kill(pid, sig);
                            });
    const char *name = sig == SIGINT ? "SIGINT" : "SIGTERM";
    EXPECT_EQ(r.exit_status, 128 + sig) << name << "\n" << r.err;
    int reason = 0;
    const int n = iterations(r.out, &reason);
    ASSERT_GE(n, 1) << r.out;
    EXPECT_EQ(reason, 9) << r.out;
    EXPECT_NE(r.out.find("\nElapsed time: "), std::string::npos) << r.out;
    EXPECT_EQ(r.err, "Starting BA with fixed intrinsic parameters\neucsbademo: interrupted by " + std::string(name) +
                         " after iteration " + std::to_string(n) + ": the results are the last accepted estimate\n");
    // The same solve run to itmax = n ends at the same estimate, byte for byte.
    const std::string cams_n = dir_ + "itmax-cams.txt", pts_n = dir_ + "itmax-pts.txt", ply_n = dir_ + "itmax.ply";
    const ChildRun full = run_child(EUCSBADEMO_EXE,
                               args({"--itmax=" + std::to_string(n), "--write-cams=" + cams_n, "--write-pts=" + pts_n,
                                     "--final-ply=" + ply_n}),
                               dir_ + "full", [](pid_t, const std::string &) {});
    ASSERT_EQ(full.exit_status, 0) << full.err;
    EXPECT_NE(full.out.find("in " + std::to_string(n) + " iter, reason 3,"), std::string::npos) << full.out;
    EXPECT_EQ(slurp(cams), slurp(cams_n)) << name;
    EXPECT_EQ(slurp(pts), slurp(pts_n)) << name;
    EXPECT_EQ(slurp(ply), slurp(ply_n)) << name;
    EXPECT_FALSE(slurp(ply).empty()) << name;
    EXPECT_NE(slurp(cams), slurp(dir_ + "big-cams.txt"));
  }
}

// A signal that stops the solve also abandons the covariance of --write-stddev, which starts
// after it: the stopped solve's results are written, the standard deviations are not.
TEST_F(EucsbademoStop, SignalDuringTheSolveSkipsTheStandardDeviations) {
  const std::string cams = dir_ + "sd-stopped-cams.txt", sd = dir_ + "sd.txt";
  const ChildRun r = run_child(EUCSBADEMO_EXE, args({"--write-cams=" + cams, "--write-stddev=" + sd}), dir_ + "sd",
                               [](pid_t pid, const std::string &err) {
                                 ASSERT_TRUE(wait_for(err, "Starting BA"));
                                 std::this_thread::sleep_for(std::chrono::milliseconds(800));
                                 kill(pid, SIGINT);
                               });
  const int n = stopped_after(r, SIGINT);
  EXPECT_EQ(r.err, "Starting BA with fixed intrinsic parameters\neucsbademo: interrupted by SIGINT after iteration " +
                       std::to_string(n) + ": the results are the last accepted estimate\neucsbademo: SIGINT: the "
                       "covariance is abandoned, " + sd + " is not written\n");
  EXPECT_FALSE(exists(sd));
  EXPECT_NE(slurp(cams), "");
}

TEST_F(EucsbademoStop, SecondSignalEndsTheProgramAtOnce) {
  const std::string cams = dir_ + "twice-cams.txt", ply = dir_ + "twice.ply";
  std::remove(cams.c_str());
  std::remove(ply.c_str());
  const ChildRun r = run_child(EUCSBADEMO_EXE, args({"--write-cams=" + cams, "--final-ply=" + ply}), dir_ + "twice",
                          [](pid_t pid, const std::string &err) {
                            ASSERT_TRUE(wait_for(err, "Starting BA"));
                            std::this_thread::sleep_for(std::chrono::milliseconds(300));
                            kill(pid, SIGINT);
                            ASSERT_TRUE(wait_delivered(pid, SIGINT));
                            kill(pid, SIGINT);
                          });
  EXPECT_EQ(r.exit_status, 130);
  EXPECT_EQ(r.out, "");  // no summary: it did not wait for the iteration to end
  EXPECT_EQ(r.err, "Starting BA with fixed intrinsic parameters\neucsbademo: stopped at once by a second signal\n");
  EXPECT_FALSE(exists(cams));
  EXPECT_FALSE(exists(ply));
}

// A signal that comes once the solve has ended stops nothing: the program abandons the files it
// has not published yet and ends with the signal's status. The signal is sent while eucsbademo
// waits to write the points into a FIFO that nobody reads yet, after its solve.
TEST_F(EucsbademoStop, SignalAfterTheSolveAbandonsTheFiles) {
  const std::string fifo = dir_ + "late.fifo", cams = dir_ + "late-cams.txt", ply = dir_ + "late.ply";
  std::remove(fifo.c_str());
  std::remove(cams.c_str());
  std::remove(ply.c_str());
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const std::string data = std::string(SBA_PROJECT_DIR) + "/data/orbit-fixedK-";
  const ChildRun r = run_child(EUCSBADEMO_EXE,
                               {"--no-progress", "--write-cams=" + cams, "--final-ply=" + ply, "--write-pts=" + fifo,
                                data + "cams.txt", data + "pts.txt", data + "calib.txt"},
                               dir_ + "late", [&](pid_t pid, const std::string &err) {
                                 ASSERT_TRUE(wait_for(err, "Starting BA"));
                                 std::this_thread::sleep_for(std::chrono::milliseconds(500));
                                 kill(pid, SIGINT);
                                 ASSERT_TRUE(wait_delivered(pid, SIGINT));
                                 EXPECT_FALSE(slurp(fifo).empty());  // opens it: the program goes on
                               });
  EXPECT_EQ(r.exit_status, 130) << r.err;
  int reason = 0;
  EXPECT_GE(iterations(r.out, &reason), 1) << r.out;
  EXPECT_NE(reason, 9);
  EXPECT_EQ(r.err, "Starting BA with fixed intrinsic parameters\neucsbademo: interrupted by SIGINT after the solve: "
                   "no file written\n");
  EXPECT_FALSE(exists(cams));
  EXPECT_FALSE(exists(ply));
  std::remove(fifo.c_str());
}

// A program started with SIGINT ignored (a background job of a script) leaves it ignored: the
// solve runs to its end, and SIGTERM still stops it.
TEST_F(EucsbademoStop, IgnoredSignalStaysIgnored) {
  const auto send = [](int sig) {
    return [sig](pid_t pid, const std::string &err) {
      ASSERT_TRUE(wait_for(err, "Starting BA"));
      std::this_thread::sleep_for(std::chrono::milliseconds(800));
      kill(pid, sig);
    };
  };
  const ChildRun ignored = run_child(EUCSBADEMO_EXE, args({"--itmax=2"}), dir_ + "ignored", send(SIGINT), SIGINT);
  EXPECT_EQ(ignored.exit_status, 0) << ignored.err;
  int reason = 0;
  EXPECT_EQ(iterations(ignored.out, &reason), 2) << ignored.out;
  EXPECT_EQ(reason, 3);
  const ChildRun term = run_child(EUCSBADEMO_EXE, args({}), dir_ + "term", send(SIGTERM), SIGINT);
  EXPECT_GE(stopped_after(term, SIGTERM), 1);
}

TEST_F(EucsbademoStop, MaxTimeStopsWithStatusZero) {
  const ChildRun r = run_child(EUCSBADEMO_EXE, args({"--max-time=0.5"}), dir_ + "maxtime", [](pid_t, const std::string &) {});
  EXPECT_EQ(r.exit_status, 0) << r.err;
  int reason = 0;
  const int n = iterations(r.out, &reason);
  ASSERT_GE(n, 1) << r.out;
  EXPECT_EQ(reason, 9);
  EXPECT_EQ(r.err, "Starting BA with fixed intrinsic parameters\neucsbademo: --max-time 0.5 s reached after iteration " +
                       std::to_string(n) + ": the results are the last accepted estimate\n");
}

// Ctrl-C during the covariance of --write-stddev abandons it, as pysba's does: the solve's
// result is written, the same bytes as a run without --write-stddev, the standard deviations
// are not, and the status says a signal cut the run short. 60 cameras and 60,000 points: one
// iteration takes a fraction of a second, the covariance seconds, nearly all of them in the
// points' blocks, where the library polls its cancel callback (a large camera system would
// spend them in its eigendecomposition, which cannot be interrupted); the signal is sent once
// the iteration's line (--verbose=2) is out.
TEST(EucsbademoCovarianceStop, SignalAbandonsTheCovarianceAndKeepsTheResult) {
  const std::string dir = sbatest::scratch_dir() + "test_interrupt_cov." + std::to_string(getpid()) + "/";
  ASSERT_EQ(std::system(("mkdir -p " + dir).c_str()), 0);
  const std::string gen = std::string(SBAGEN_EXE) + " --quiet --out " + dir +
                          "cov --cameras 60 --points 60000 --perturb-rotation 0.03 --perturb-points 0.05 --seed 3";
  ASSERT_EQ(std::system(gen.c_str()), 0) << gen;
  const auto args = [&](const std::string &out, std::vector<std::string> extra) {
    extra.insert(extra.end(), {"--solver=chol", "--threads=1", "--no-progress", "--itmax=1", "--write-cams=" + out +
                               "-cams.txt", "--write-pts=" + out + "-pts.txt", "--final-ply=" + out + ".ply"});
    for (const char *f : {"cov-cams.txt", "cov-pts.txt", "cov-calib.txt"}) extra.push_back(dir + f);
    return extra;
  };
  const std::string sd = dir + "sd.txt";
  const ChildRun r = run_child(EUCSBADEMO_EXE, args(dir + "stopped", {"--verbose=2", "--write-stddev=" + sd}),
                               dir + "run", [&](pid_t pid, const std::string &) {
                                 ASSERT_TRUE(wait_for(dir + "run.out", "damping term"));
                                 std::this_thread::sleep_for(std::chrono::milliseconds(200));
                                 kill(pid, SIGINT);
                               });
  EXPECT_EQ(r.exit_status, 130) << r.err;
  EXPECT_EQ(r.err, "Starting BA with fixed intrinsic parameters\neucsbademo: SIGINT: the covariance is abandoned, " +
                       sd + " is not written\n");
  int reason = 0;
  EXPECT_EQ(iterations(r.out, &reason), 1) << r.out;
  EXPECT_EQ(reason, 3);  // the solve ended as asked (itmax), before the signal
  EXPECT_FALSE(exists(sd));
  const ChildRun full = run_child(EUCSBADEMO_EXE, args(dir + "full", {}), dir + "full", [](pid_t, const std::string &) {});
  ASSERT_EQ(full.exit_status, 0) << full.err;
  for (const char *part : {"-cams.txt", "-pts.txt", ".ply"}) {
    EXPECT_EQ(slurp(dir + "stopped" + part), slurp(dir + "full" + part)) << part;
    EXPECT_FALSE(slurp(dir + "stopped" + part).empty()) << part;
  }
  ASSERT_EQ(std::system(("rm -rf " + dir).c_str()), 0);
}

TEST(BalsbaStop, SignalStopsWithTheLastAcceptedEstimate) {
  const std::string problem = std::string(SBA_SHARED_DATA_DIR) + "/bal/problem-49-7776-pre.txt.bz2";
  if (!exists(problem)) GTEST_SKIP() << problem << " is absent";
  const std::string base = sbatest::scratch_dir() + "test_interrupt_bal." + std::to_string(getpid());
  const std::string out = base + "-stopped.txt", out_n = base + "-itmax.txt";
  const std::string ply = base + "-stopped.ply", ply_n = base + "-itmax.ply";
  const std::vector<std::string> common{problem, "--solver=svd", "--threads=1", "--no-progress"};
  std::vector<std::string> a = common;
  a.insert(a.end(), {"--write", out, "--final-ply", ply});
  const ChildRun r = run_child(BALSBA_EXE, a, base, [](pid_t pid, const std::string &) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2000));  // reading the file takes a fraction of it
    kill(pid, SIGINT);
  });
  const int n = stopped_after(r, SIGINT);
  ASSERT_GE(n, 1);
  EXPECT_EQ(r.err, "balsba: interrupted by SIGINT after iteration " + std::to_string(n) +
                       ": the results are the last accepted estimate\n");
  a = common;
  a.insert(a.end(), {"--itmax", std::to_string(n), "--write", out_n, "--final-ply", ply_n});
  const ChildRun full = run_child(BALSBA_EXE, a, base + "-full", [](pid_t, const std::string &) {});
  ASSERT_EQ(full.exit_status, 0) << full.err;
  EXPECT_EQ(slurp(out), slurp(out_n));
  EXPECT_FALSE(slurp(out).empty());
  EXPECT_EQ(slurp(ply), slurp(ply_n));
  EXPECT_FALSE(slurp(ply).empty());
  for (const std::string &f : {out, out_n, ply, ply_n}) std::remove(f.c_str());
}

TEST(BalsbaStop, MaxTimeStopsWithStatusZero) {
  const std::string problem = std::string(SBA_SHARED_DATA_DIR) + "/bal/problem-49-7776-pre.txt.bz2";
  if (!exists(problem)) GTEST_SKIP() << problem << " is absent";
  const std::string base = sbatest::scratch_dir() + "test_interrupt_bal_time." + std::to_string(getpid());
  const ChildRun r = run_child(BALSBA_EXE, {problem, "--solver=svd", "--threads=1", "--max-time", "0.5"}, base,
                               [](pid_t, const std::string &) {});
  EXPECT_EQ(r.exit_status, 0) << r.err;
  int reason = 0;
  const int n = iterations(r.out, &reason);
  ASSERT_GE(n, 1) << r.out;
  EXPECT_EQ(reason, 9);
  EXPECT_NE(r.out.find("\nStop reason 9: stopped on request (a signal or --max-time)\n"), std::string::npos) << r.out;
  EXPECT_EQ(r.err, "balsba: --max-time 0.5 s reached after iteration " + std::to_string(n) +
                       ": the results are the last accepted estimate\n");
}

}  // namespace
