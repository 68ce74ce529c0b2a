// SPDX-License-Identifier: BSD-3-Clause
// Faults that tests/test_drivers.cpp does not cover: Jacobians of the wrong sign,
// callbacks that fail mid-way in every driver, callbacks that throw, running out of memory,
// problems too large for the int API, and every bad argument of every one of the six drivers.
//
// The tests that could hang or kill the process (a wrong Jacobian that never stops, an
// allocation failure that escapes) run the solve in a fork()ed child under alarm(), so that
// a regression is a failed test with a reason, not a stuck or crashed test binary.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <malloc.h>
#include <pthread.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <limits>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#include "counting_new.h"
#include "faults.h"
#include "sba.h"
#include "sba_ext.h"
#include "synth.h"

namespace {

using namespace faults;

// ---------------------------------------------------------------- a solve in a child process

struct ChildOutcome {
  bool exited = false;  // exited normally (else killed by `signal`)
  int code = -1;        // exit status
  int signal = 0;
  std::string err;      // what the child wrote to stderr
  std::string data;     // what the child wrote to its report pipe
  double seconds = 0;

  std::string describe() const {
    std::string s = exited ? "exited with " + std::to_string(code)
                           : "killed by signal " + std::to_string(signal) +
                                 (signal == SIGALRM ? " (SIGALRM: did not finish in time)" : "");
    return s + " after " + std::to_string(seconds) + " s; stderr: " + err;
  }
};

// Runs body(report_fd) in a fork()ed child whose stderr goes to a file the parent reads
// back; the child is killed by SIGALRM after timeout_s seconds. The child ends with
// _exit(body's return value), so nothing of the test framework runs twice.
ChildOutcome run_in_child(const std::function<int(int)> &body, unsigned timeout_s) {
  ChildOutcome out;
  std::FILE *errf = std::tmpfile();
  int fds[2];
  if (!errf || pipe(fds) != 0) {
    ADD_FAILURE() << "cannot create the child's stderr file or pipe";
    return out;
  }
  std::fflush(stdout);
  std::fflush(stderr);
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid < 0) {
    ADD_FAILURE() << "fork failed";
    return out;
  }
  if (pid == 0) {
    close(fds[0]);
    dup2(fileno(errf), 2);
    alarm(timeout_s);
    const int code = body(fds[1]);
    close(fds[1]);
    _exit(code);
  }
  close(fds[1]);
  char buf[4096];
  for (ssize_t r; (r = read(fds[0], buf, sizeof buf)) != 0;) {
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) break;
    out.data.append(buf, size_t(r));
  }
  close(fds[0]);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.exited = WIFEXITED(status);
  out.code = out.exited ? WEXITSTATUS(status) : -1;
  out.signal = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
  std::rewind(errf);
  for (size_t r; (r = std::fread(buf, 1, sizeof buf, errf)) > 0;) out.err.append(buf, r);
  std::fclose(errf);
  return out;
}

// The fixed-size record a child sends back.
struct Report {
  int ret = 0;
  double info[SBA_INFOSZ] = {};
  long leaked = 0;      // C++ allocations not given back by the call
  int p_changed = 0;    // p differs from the start
  int p_finite = 1;
  int error_matches = 1;  // info[1] is the error of the returned p
};

void send(int fd, const Report &r) {
  const char *b = reinterpret_cast<const char *>(&r);
  for (size_t done = 0; done < sizeof r;) {
    const ssize_t w = write(fd, b + done, sizeof r - done);
    if (w <= 0) return;
    done += size_t(w);
  }
}

bool receive(const ChildOutcome &c, Report *r) {
  if (c.data.size() != sizeof *r) return false;
  std::memcpy(static_cast<void *>(r), c.data.data(), sizeof *r);
  return true;
}

// ---------------------------------------------------------------- wrong Jacobians

// A Jacobian of the wrong sign points every step uphill: the attempts are rejected and the
// damping grows until the solve gives up. It must give up, quickly and without making the
// error worse: reason 6 (the damping cannot grow any more) or, with the default eps2, reason 2
// (the damped steps have become negligible). Never an endless loop.
TEST(Faults, NegatedJacobianStopsWithoutLoopingInEveryDriver) {
  for (Driver d : kAllDrivers) {
    for (bool strict : {false, true}) {
      SCOPED_TRACE(std::string(name_of(d)) + (strict ? " with eps1..eps4 = 0" : " with the defaults"));
      Rig su(d, 60, 5, 0.3, 101);
      su.sab.kind = Sabotage::NegatedJac;
      // eps2 = 0 takes away the small-step exit: only the damping limit is left.
      const double strict_opts[SBA_OPTSSZ] = {1e-3, 0.0, 0.0, 0.0, 0.0};
      const ChildOutcome c = run_in_child(
          [&](int fd) {
            Call call_args = su.base();
            call_args.itmax = 1000;
            call_args.opts = strict ? strict_opts : nullptr;
            Report r;
            r.ret = call(d, call_args, &su.sab);
            std::copy(su.info, su.info + SBA_INFOSZ, r.info);
            r.p_changed = su.p != su.p0;
            r.p_finite = all_finite(su.p);
            send(fd, r);
            return 0;
          },
          60);
      ASSERT_TRUE(c.exited && c.code == 0) << c.describe();
      Report r;
      ASSERT_TRUE(receive(c, &r));
      EXPECT_LT(c.seconds, 30.0);
      if (r.ret == SBA_ERROR) {
        // A clear failure is acceptable too: it must say why.
        EXPECT_FALSE(c.err.empty());
      } else {
        EXPECT_GE(r.ret, 1);
        EXPECT_LT(r.ret, 1000) << "ran to itmax: every step was rejected without giving up";
        if (strict)
          EXPECT_EQ(r.info[6], 6) << c.err;
        else
          EXPECT_TRUE(r.info[6] == 6 || r.info[6] == 2) << r.info[6];
      }
      EXPECT_LE(r.info[1], r.info[0]);
      EXPECT_TRUE(r.p_finite);
    }
  }
}

// A Jacobian that is right at first and turns to the wrong sign later: the estimate
// accepted so far is kept and the solve ends.
TEST(Faults, JacobianThatTurnsWrongMidwayKeepsTheLastAcceptedEstimate) {
  for (Driver d : {Driver::MotStrX, Driver::MotStr}) {
    SCOPED_TRACE(name_of(d));
    Rig su(d, 60, 5, 0.3, 102);
    su.sab.kind = Sabotage::NegatedJac;
    // Expert: after 2 Jacobians; simple: after 2 Jacobians' worth of projections.
    su.sab.after = is_expert(d) ? 2 : 2 * su.pb.nvis;
    const ChildOutcome c = run_in_child(
        [&](int fd) {
          Call call_args = su.base();
          call_args.itmax = 1000;
          Report r;
          r.ret = call(d, call_args, &su.sab);
          std::copy(su.info, su.info + SBA_INFOSZ, r.info);
          r.p_finite = all_finite(su.p);
          r.p_changed = su.p != su.p0;
          r.error_matches = std::fabs(su.sq_error_of(su.p) - su.info[1]) <= 1e-9 * su.info[1];
          send(fd, r);
          return 0;
        },
        60);
    ASSERT_TRUE(c.exited && c.code == 0) << c.describe();
    Report r;
    ASSERT_TRUE(receive(c, &r));
    ASSERT_GE(r.ret, 2) << c.err;
    EXPECT_LT(r.ret, 1000);
    EXPECT_TRUE(r.info[6] == 6 || r.info[6] == 2) << r.info[6];
    EXPECT_LT(r.info[1], r.info[0]);  // the good iterations were kept
    EXPECT_TRUE(r.p_changed);
    EXPECT_TRUE(r.p_finite);
    EXPECT_TRUE(r.error_matches) << "info[1] is not the error of the returned p";
  }
}

// ---------------------------------------------------------------- NaN/Inf mid-way, every driver

// test_drivers.cpp covers NaN from func mid-way and a NaN Jacobian at the start for the
// motion+structure expert driver; here every driver, NaN and Inf, values and Jacobians, all
// after some successful iterations.
TEST(Faults, NonFiniteCallbackMidwayIsReason7WithTheLastAcceptedEstimateInEveryDriver) {
  for (Driver d : kAllDrivers)
    for (Sabotage::Kind kind : {Sabotage::NanValue, Sabotage::InfValue, Sabotage::NanJac}) {
      SCOPED_TRACE(std::string(name_of(d)) + " fault " + std::to_string(int(kind)));
      Rig su(d, 60, 5, 0.3, 103);
      su.sab.kind = kind;
      const long per_call = is_expert(d) ? 1 : su.pb.nvis;  // simple callbacks: per projection
      su.sab.after = int((kind == Sabotage::NanJac ? 2 : 3) * per_call);
      Call c = su.base();
      testing::internal::CaptureStderr();
      const int ret = call(d, c, &su.sab);
      const std::string err = testing::internal::GetCapturedStderr();
      EXPECT_EQ(ret, SBA_ERROR);
      EXPECT_EQ(su.info[6], 7);
      EXPECT_NE(err.find("NaN or Inf"), std::string::npos) << err;
      // p is the last accepted estimate, not the failed trial point: finite, better than the
      // start, and scored by info[1].
      EXPECT_TRUE(all_finite(su.p));
      EXPECT_LT(su.info[1], su.info[0]);
      EXPECT_NEAR(su.sq_error_of(su.p), su.info[1], 1e-9 * su.info[1]);
    }
}

TEST(Faults, NonFiniteValueAtTheStartLeavesPUntouchedInEveryDriver) {
  for (Driver d : kAllDrivers) {
    SCOPED_TRACE(name_of(d));
    Rig su(d, 40, 4, 0.3, 104);
    su.sab.kind = Sabotage::InfValue;
    Call c = su.base();
    testing::internal::CaptureStderr();
    const int ret = call(d, c, &su.sab);
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_EQ(ret, SBA_ERROR);
    EXPECT_EQ(su.info[6], 7);
    EXPECT_NE(err.find("initial estimate"), std::string::npos) << err;
    EXPECT_EQ(su.p, su.p0);
  }
}

// One call of d with its stderr captured and the allocations it did not give back counted.
struct Captured {
  int ret;
  long leaked;
  std::string err;
};
Captured call_counting(Driver d, const Call &c, Rig &su) {
  testing::internal::CaptureStderr();
  const long live = g_live_news.load();
  const int ret = call(d, c, &su.sab);
  const long leaked = g_live_news.load() - live;
  return Captured{ret, leaked, testing::internal::GetCapturedStderr()};
}

// With the Jacobian in single precision the simple drivers keep no residual: an evaluation
// sums the error as proj gives it, and the linearization calls proj again beside projac.
// A NaN or Inf from proj (mid-way: in an evaluation or in a linearization; at the start) or
// from projac fails the solve as in double, with p the last accepted estimate; one that throws
// gives back every allocation.
TEST(Faults, SpoiledCallbacksWithTheJacobianInSinglePrecision) {
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.single_precision_jacobian = 1;
  for (Driver d : {Driver::MotStr, Driver::Mot, Driver::Str})
    for (Sabotage::Kind kind : {Sabotage::NanValue, Sabotage::InfValue, Sabotage::NanJac, Sabotage::ThrowValue})
      for (long calls : {0L, 3L, 4L}) {
        SCOPED_TRACE(std::string(name_of(d)) + " fault " + std::to_string(int(kind)) + " after " +
                     std::to_string(calls));
        Rig su(d, 60, 5, 0.3, 107);
        su.sab.kind = kind;
        su.sab.after = calls * su.pb.nvis;
        Call c = su.base();
        c.ext = &ext;
        const Captured r = call_counting(d, c, su);
        const std::string &err = r.err;
        EXPECT_EQ(r.leaked, 0) << "allocations not given back";
        EXPECT_EQ(r.ret, SBA_ERROR);
        EXPECT_TRUE(su.sab.fired.load());
        if (kind == Sabotage::ThrowValue) {
          EXPECT_NE(err.find("callback failure injected by the test"), std::string::npos) << err;
          continue;
        }
        EXPECT_EQ(su.info[6], 7);
        EXPECT_NE(err.find("NaN or Inf"), std::string::npos) << err;
        if (calls == 0 && kind != Sabotage::NanJac) {
          EXPECT_NE(err.find("initial estimate"), std::string::npos) << err;
          EXPECT_EQ(su.p, su.p0);
          continue;
        }
        EXPECT_TRUE(all_finite(su.p));
        EXPECT_NEAR(su.sq_error_of(su.p), su.info[1], 1e-9 * su.info[1]);
      }
}

// A C++ callback that throws must not take the caller down with it (nor leak).
TEST(Faults, ThrowingCallbackIsAnErrorAndFreesEverything) {
  for (Driver d : kAllDrivers)
    for (bool fd_jacobian : {false, true}) {
      SCOPED_TRACE(std::string(name_of(d)) + (fd_jacobian ? " (finite differences)" : ""));
      Rig su(d, 40, 4, 0.3, 105);
      su.sab.kind = Sabotage::ThrowValue;
      su.sab.after = int(2 * (is_expert(d) ? 1 : su.pb.nvis));
      Call c = su.base();
      c.jac = !fd_jacobian;
      const Captured r = call_counting(d, c, su);
      EXPECT_EQ(r.leaked, 0) << "allocations not given back";
      EXPECT_EQ(r.ret, SBA_ERROR);
      EXPECT_NE(r.err.find("callback failure injected by the test"), std::string::npos) << r.err;
      EXPECT_TRUE(all_finite(su.p));
    }
}

// ---------------------------------------------------------------- out of memory

// (1) Every C++ allocation of a solve, one at a time, made to fail by the counting operator
// new of counting_new.h: each must end in SBA_ERROR with "out of memory" and give back
// everything.

// Collects error lines without allocating (the sink runs inside the failure window).
struct ErrorLines {
  char text[4096] = {};
  size_t len = 0;
  int lines = 0;
  static void sink(void *ctx, int level, const char *line) {
    ErrorLines &e = *static_cast<ErrorLines *>(ctx);
    if (level != SBA_LOG_ERROR) return;
    ++e.lines;
    for (const char *c = line; *c && e.len + 2 < sizeof e.text; ++c) e.text[e.len++] = *c;
    if (e.len + 1 < sizeof e.text) e.text[e.len++] = '\n';
  }
  bool has(const char *what) const { return std::strstr(text, what) != nullptr; }
};

// ---------------------------------------------------------------- a thread ended in a callback

// pthread_exit in a callback (as glibc's cancellation, or Python ending a daemon thread that
// takes the GIL in a callback while the interpreter exits) is a forced unwind: the thread that
// runs the solve ends, the process goes on, and everything the solve held is given back.
struct EndedSolve {
  synth::Problem pb;
  std::vector<double> p;
  pthread_t caller{};
  int end_at_iteration = 0;       // the progress callback ends the calling thread there
  bool end_a_worker = false;      // func ends the first worker thread it runs on
  std::atomic<int> worker_calls{0};
  int ret = 1234;                 // the driver's return value, if it returned
  ErrorLines errors;

  static int progress(void *ctx, const sba_progress *state) {
    if (state->iteration == static_cast<EndedSolve *>(ctx)->end_at_iteration) pthread_exit(nullptr);
    return 0;
  }
  static void func(double *p, sba_crsm *idx, int *rcidxs, int *rcsubs, double *hx, void *adata) {
    EndedSolve &s = *static_cast<EndedSolve *>(adata);
    if (s.end_a_worker && !pthread_equal(pthread_self(), s.caller) && s.worker_calls.fetch_add(1) == 0)
      pthread_exit(nullptr);
    // The caller, done with its part of a job, would do a worker's part that has not begun:
    // its first call waits (a few seconds at most) for the worker's, so that one is made.
    for (int k = 0; k < 5000 && s.end_a_worker && s.worker_calls.load() == 0; ++k) usleep(1000);
    synth::func_motstr(p, idx, rcidxs, rcsubs, hx, &s.pb);
  }
  static void *solve(void *arg) {
    EndedSolve &s = *static_cast<EndedSolve *>(arg);
    s.caller = pthread_self();
    sba_ext_options ext;
    sba_ext_options_init(&ext);
    ext.nthreads = 2;
    ext.parallel_callbacks = 1;
    ext.progress = progress;
    ext.progress_ctx = &s;
    ext.log = ErrorLines::sink;
    ext.log_ctx = &s.errors;
    double info[SBA_INFOSZ];
    s.ret = sba_motstr_levmar_x_ext(s.pb.n, 0, s.pb.m, 1, s.pb.vmask.data(), s.p.data(), synth::kCnp,
                                    synth::kPnp, s.pb.x.data(), nullptr, synth::kMnp, func, synth::fjac_motstr,
                                    &s, 20, 0, nullptr, info, &ext);
    return nullptr;
  }
};

TEST(Faults, ForcedUnwindInACallbackEndsOnlyTheThreadAndFreesEverything) {
  for (bool worker : {false, true}) {
    SCOPED_TRACE(worker ? "a worker ended in func" : "the calling thread ended in progress");
    const ChildOutcome c = run_in_child(
        [worker](int fd) {
          EndedSolve s;
          s.pb = synth::make(200, 6, 0.3, 0.05, 115);
          s.p = s.pb.p0;
          s.end_at_iteration = worker ? 0 : 2;
          s.end_a_worker = worker;
          const long live = g_live_news.load();
          pthread_t t;
          if (pthread_create(&t, nullptr, EndedSolve::solve, &s) != 0) return 3;
          pthread_join(t, nullptr);
          const long leaked = g_live_news.load() - live;
          std::string line = "ret=" + std::to_string(s.ret) + " leaked=" + std::to_string(leaked) + "\n" +
                             std::string(s.errors.text, s.errors.len);
          // The process goes on: a solve in the main thread works as ever.
          std::vector<double> p = s.pb.p0;
          double info[SBA_INFOSZ];
          const int again = sba_motstr_levmar_x(s.pb.n, 0, s.pb.m, 1, s.pb.vmask.data(), p.data(), synth::kCnp,
                                                synth::kPnp, s.pb.x.data(), nullptr, synth::kMnp, synth::func_motstr,
                                                synth::fjac_motstr, &s.pb, 20, 0, nullptr, info);
          line += "again=" + std::string(again > 0 ? "ok" : "failed");
          if (write(fd, line.data(), line.size()) < 0) return 4;
          return 0;
        },
        60);
    ASSERT_TRUE(c.exited && c.code == 0) << c.describe();
    // Unwound, not returned, when the calling thread ends; an SBA_ERROR naming the lost
    // worker when a worker does. Either way nothing is leaked.
    const std::string expected = worker ? "ret=-1 leaked=0\nsba_motstr_levmar_x: internal error: a worker thread of "
                                          "the solve was ended (pthread_exit or pthread_cancel in a callback)\n"
                                        : "ret=1234 leaked=0\n";
    EXPECT_EQ(c.data, expected + "again=ok");
  }
}

struct InjectCase {
  const char *what;
  Driver driver;
  const char *linsolver;
  int nthreads;
  bool fd_jacobian, covx;
  const char *loss;
  bool covariance;  // sba_motstr_covariance_x instead of the driver
};

#ifndef SBA_TEST_SANITIZED
void check_every_allocation_may_fail(const InjectCase &ic) {
  SCOPED_TRACE(ic.what);
  Rig su(ic.driver, 24, 4, 0.3, 109);
  ErrorLines errors;
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = ic.linsolver;
  ext.nthreads = ic.nthreads;
  ext.loss = ic.loss;
  ext.log = ErrorLines::sink;
  ext.log_ctx = &errors;
  std::vector<double> camcov(size_t(2) * kCnp * kCnp), ptcov(size_t(3) * kPnp * kPnp);
  const int cams[2] = {1, 3}, pts[3] = {0, 5, 23};
  auto run = [&]() {
    su.p = su.p0;
    errors = ErrorLines{};
    Call c = su.base();
    c.itmax = 3;
    c.jac = !ic.fd_jacobian;
    c.covx = ic.covx ? su.covx.data() : nullptr;
    c.ext = &ext;
    if (!ic.covariance) return call(ic.driver, c, &su.sab);
    sba_covariance_request req;
    sba_covariance_request_init(&req);
    req.ncams = 2;
    req.cams = cams;
    req.camcov = camcov.data();
    req.npts = 3;
    req.pts = pts;
    req.ptcov = ptcov.data();
    return sba_motstr_covariance_x(c.n, 0, c.m, 0, c.vmask, c.p, kCnp, kPnp, c.x, c.covx, kMnp,
                                   x_func_motstr, c.jac ? x_fjac_motstr : nullptr, &su.sab, &req, &ext);
  };
  // How many allocations a successful call makes.
  const long total0 = g_news_total.load();
  const int ok = run();
  const long total = g_news_total.load() - total0;
  ASSERT_GE(ok, 0) << errors.text;
  ASSERT_GT(total, 0);
  long failed_cleanly = 0;
  for (long k = 1; k <= total; ++k) {
    const long live = g_live_news.load();
    g_fail_countdown.store(k);
    const int ret = run();
    g_fail_countdown.store(0);
    const long leaked = g_live_news.load() - live;
    const bool clean = ret == SBA_ERROR && errors.has("out of memory") && errors.lines == 1 &&
                       leaked == 0 && all_finite(su.p);
    failed_cleanly += clean;
    if (!clean && failed_cleanly + 1 == k) {  // the first one of this case in detail
      EXPECT_EQ(ret, SBA_ERROR) << "allocation " << k << " of " << total << " failed unnoticed";
      EXPECT_TRUE(errors.has("out of memory")) << "allocation " << k << ": " << errors.text;
      EXPECT_EQ(errors.lines, 1) << "allocation " << k << ": " << errors.text;
      EXPECT_EQ(leaked, 0) << "allocation " << k << " of " << total;
      EXPECT_TRUE(all_finite(su.p));
    }
  }
  EXPECT_EQ(failed_cleanly, total) << "allocations that did not end in a clean SBA_ERROR";
}
#endif

// Allocation k of a solve fails, for every k: SBA_ERROR, one "out of memory" line, every
// allocation given back.
TEST(Faults, EveryCxxAllocationOfASolveMayFailCleanly) {
#ifdef SBA_TEST_SANITIZED
  GTEST_SKIP() << "needs the counting operator new, which the sanitizers replace";
#else
  const InjectCase cases[] = {
      {"motstr_x chol", Driver::MotStrX, "chol", 1, false, false, nullptr, false},
      {"motstr_x sparse-chol 2 threads covx", Driver::MotStrX, "sparse-chol", 2, false, true, nullptr, false},
      {"motstr_x ldl-amd finite differences", Driver::MotStrX, "ldl-amd", 1, true, false, nullptr, false},
      {"motstr_x qrnoq huber", Driver::MotStrX, "qrnoq", 2, false, false, "huber", false},
      {"motstr simple cg finite differences", Driver::MotStr, "cg", 1, true, true, nullptr, false},
      {"motstr_x iterative-schur 2 threads covx cauchy", Driver::MotStrX, "iterative-schur", 2, false, true, "cauchy", false},
      {"mot_x", Driver::MotX, nullptr, 2, false, false, nullptr, false},
      {"mot simple", Driver::Mot, nullptr, 1, true, true, nullptr, false},
      {"str_x", Driver::StrX, nullptr, 2, false, true, "tukey", false},
      {"str simple", Driver::Str, nullptr, 1, true, false, "cauchy", false},
      {"covariance_x", Driver::MotStrX, nullptr, 2, false, true, nullptr, true},
  };
  for (const InjectCase &ic : cases) check_every_allocation_may_fail(ic);
#endif
}

// The dense solvers that go through src/dense.h (ldlt, bk, lu, qr, svd) must tell an
// allocation failure from a failed factorization: were std::bad_alloc read as "singular", the
// solve would raise the damping and carry on, and under lasting memory pressure end with
// reason 6 as if the Jacobian were wrong.
TEST(Faults, EveryCxxAllocationOfASolveMayFailCleanlyWithTheHelperSolvers) {
#ifdef SBA_TEST_SANITIZED
  GTEST_SKIP() << "needs the counting operator new, which the sanitizers replace";
#else
  for (const char *solver : {"ldlt", "bk", "lu", "qr", "svd"})
    check_every_allocation_may_fail({solver, Driver::MotStrX, solver, 1, false, false, nullptr, false});
#endif
}

// (2) The real thing: an address-space limit (RLIMIT_AS), from nothing to plenty, so that
// every allocation of the solve fails in turn, C++ or not (CHOLMOD and LAPACK allocate with
// malloc; the threads need stacks). std::bad_alloc from inside the library must not escape,
// abort or exit: the call returns SBA_ERROR with "out of memory" and the process lives on.
//
// Each limited solve runs in a fresh process (this binary re-executed with
// SBA_FAULTS_OOM_CHILD set, caught before main): a forked copy of a test process carries
// heaps and malloc arenas left over from earlier tests, whose reserved address space would
// absorb the solve's allocations without ever reaching the limit.

// Current address space of this process, in bytes.
long address_space_bytes() {
  long pages = 0;
  if (std::FILE *f = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(f, "%ld", &pages) != 1) pages = 0;
    std::fclose(f);
  }
  return pages * sysconf(_SC_PAGESIZE);
}

// The child: "LINSOLVER NTHREADS SIMPLE COVX HEADROOM REPORT_FD [WARM]". Exit status 10: the
// solve returned SBA_ERROR; 11: it succeeded; 12: anything else; 3: bad spec.
int oom_child_main(const char *spec) {
  char linsolver[32];
  int nthreads = 1, simple = 0, covx = 0, fd = -1, warm = 1;
  long headroom = 0;
  if (std::sscanf(spec, "%31s %d %d %d %ld %d %d", linsolver, &nthreads, &simple, &covx, &headroom, &fd,
                  &warm) < 6)
    return 3;
  // One malloc arena for every thread: a block that the limit keeps from being mapped is
  // then not found instead in the free space of another thread's arena, whose size depends
  // on which threads ran which parts of the warm-up's jobs (the scheduler's choice).
  mallopt(M_ARENA_MAX, 1);
  // 120 cameras, 2000 points seen about 4 times: a dense S of 720 x 720 (4 MB).
  Rig su(Driver::MotStrX, 2000, 120, 0.3, 106, 4.0 / 120.0);
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = linsolver;
  ext.nthreads = nthreads;
  Call args = su.base();
  args.itmax = 5;
  args.ext = &ext;
  if (covx) args.covx = su.covx.data();
  const Driver driver = simple ? Driver::MotStr : Driver::MotStrX;
  // A first iteration without the limit, as a long-running host would have done: LAPACK's
  // one-time buffers then exist. (OpenBLAS allocates them at first use and, when that fails,
  // retries forever: a hang that is OpenBLAS's, not ours; warm = 0
  // in the spec reproduces it.)
  if (warm) {
    std::vector<double> p = su.p;
    Call first = args;
    first.itmax = 1;
    first.p = p.data();
    call(driver, first, &su.sab);
  }
  // Large blocks from mmap and no free heap left from the set-up: the limit then bites on
  // the solve's own allocations.
  mallopt(M_MMAP_THRESHOLD, 64 * 1024);
  malloc_trim(0);
  rlimit old{};
  getrlimit(RLIMIT_AS, &old);
  rlimit low = old;
  low.rlim_cur = rlim_t(address_space_bytes() + headroom);
  if (old.rlim_max != RLIM_INFINITY && low.rlim_cur > old.rlim_max) low.rlim_cur = old.rlim_max;
  const long live = g_live_news.load();
  if (setrlimit(RLIMIT_AS, &low) != 0) return 3;
  Report r;
  r.ret = call(driver, args, &su.sab);
  setrlimit(RLIMIT_AS, &old);
  r.leaked = g_live_news.load() - live;
  std::copy(su.info, su.info + SBA_INFOSZ, r.info);
  r.p_finite = all_finite(su.p);
  r.p_changed = su.p != su.p0;
  send(fd, r);
  return r.ret == SBA_ERROR ? 10 : r.ret > 0 ? 11 : 12;
}

const int g_oom_child = [] {
  if (const char *spec = std::getenv("SBA_FAULTS_OOM_CHILD")) _exit(oom_child_main(spec));
  return 0;
}();

struct OomCase {
  const char *linsolver;
  int nthreads;
  bool simple;  // the simple motstr driver (else the expert one)
  bool covx;
};

ChildOutcome solve_with_headroom(const OomCase &oc, long headroom, Report *report) {
  ChildOutcome c = run_in_child(
      [&](int fd) {
        const std::string spec = std::string(oc.linsolver) + " " + std::to_string(oc.nthreads) + " " +
                                 std::to_string(int(oc.simple)) + " " + std::to_string(int(oc.covx)) +
                                 " " + std::to_string(headroom) + " " + std::to_string(fd) + " 1";
        setenv("SBA_FAULTS_OOM_CHILD", spec.c_str(), 1);
        // OpenBLAS's threaded level-3 routines (CHOLMOD's dsyrk) allocate a buffer per call
        // and exit the process when that fails: OpenBLAS's behaviour, which no caller can
        // catch. The sweep is of the library's own allocations, so OpenBLAS runs on one
        // thread, whose buffers the warm-up iteration made.
        setenv("OPENBLAS_NUM_THREADS", "1", 1);
        execl("/proc/self/exe", "test_faults", static_cast<char *>(nullptr));
        return 4;
      },
      120);
  if (!receive(c, report)) *report = Report{};
  return c;
}

void check_out_of_memory_sweep(const OomCase &oc) {
  int failures = 0, successes = 0;
  for (long headroom = 0; headroom <= (256L << 20); headroom = headroom ? headroom * 2 : (64L << 10)) {
    SCOPED_TRACE("headroom " + std::to_string(headroom >> 10) + " KiB");
    Report r;
    const ChildOutcome c = solve_with_headroom(oc, headroom, &r);
    EXPECT_TRUE(c.exited && (c.code == 10 || c.code == 11)) << c.describe();
    if (!c.exited || (c.code != 10 && c.code != 11)) continue;
    if (c.code == 10) {
      ++failures;
      EXPECT_NE(c.err.find("out of memory"), std::string::npos) << c.err;
      EXPECT_EQ(r.info[6], 0) << c.err;
      EXPECT_TRUE(r.p_finite);
    } else {
      ++successes;
    }
    EXPECT_EQ(r.leaked, 0) << "C++ allocations not given back; " << c.describe();
  }
  EXPECT_GT(failures, 0) << "no limit was low enough to fail";
  EXPECT_GT(successes, 0) << "even the largest limit failed";
}

TEST(Faults, AddressSpaceLimitIsACleanErrorAndFreesEverything) {
#ifdef SBA_TEST_SANITIZED
  GTEST_SKIP() << "RLIMIT_AS cannot work under a sanitizer (it reserves terabytes of shadow "
                  "memory); the sanitizers check leaks themselves";
#else
  const OomCase cases[] = {
      {"chol", 1, false, false}, {"chol", 2, true, true}, {"ldl-amd", 2, false, true},
      {"lu", 1, false, false},   {"cg", 1, true, false}, {"iterative-schur", 2, false, true},
  };
  for (const OomCase &oc : cases) {
    SCOPED_TRACE(std::string(oc.linsolver) + " threads " + std::to_string(oc.nthreads) +
                 (oc.simple ? " simple" : " expert") + (oc.covx ? " covx" : ""));
    check_out_of_memory_sweep(oc);
  }
#endif
}

// CHOLMOD under the limit. Its OpenMP regions run in libgomp, which calls exit(1) ("Thread
// creation failed") when it cannot start a thread; the warm first iteration of the child has
// already started libgomp's pool, as a long-running host would have, so what is tested here is
// CHOLMOD's and our own allocations. A process whose very first sparse solve meets the limit
// can still be ended by libgomp (README, "Reliability", known limits).
TEST(Faults, AddressSpaceLimitWithSparseCholIsACleanError) {
#ifdef SBA_TEST_SANITIZED
  GTEST_SKIP() << "RLIMIT_AS cannot work under a sanitizer";
#else
  check_out_of_memory_sweep({"sparse-chol", 1, false, false});
#endif
}

// ---------------------------------------------------------------- the int API

// Sizes whose products do not fit the int offsets that 1.6-style callbacks use are refused
// before anything of that size is touched (p and x here are far shorter than such a problem
// would need: the refusal must come first).
TEST(Faults, ProductsBeyondTheIntApiAreRefused) {
  std::vector<double> p(64, 0.0), x(64, 0.0);
  double info[SBA_INFOSZ];
  struct Big {
    const char *what;
    int n, m, cnp, pnp, mnp;
    long visible;  // the first `visible` cells of vmask are set
  };
  const Big cases[] = {
      // nvis * mnp: 1024 projections of 2^21 coordinates each
      {"nvis*mnp", 1024, 1, 1, 1, 1 << 21, 1024},
      // the Jacobian nvis * mnp * (cnp + pnp): 2^20 projections * 2 * 1024
      {"jacobian", 1024, 1024, 512, 512, 2, 1L << 20},
      // the parameters m*cnp + n*pnp: 2^21 points of 1024 parameters, one projection
      {"parameters", 1 << 21, 1, 6, 1024, 2, 1},
  };
  for (const Big &b : cases) {
    SCOPED_TRACE(b.what);
    std::vector<char> vmask(size_t(b.n) * size_t(b.m), 0);
    std::fill(vmask.begin(), vmask.begin() + b.visible, 1);
    testing::internal::CaptureStderr();
    const int ret = sba_motstr_levmar_x(b.n, 0, b.m, 0, vmask.data(), p.data(), b.cnp, b.pnp,
                                        x.data(), nullptr, b.mnp, synth::func_motstr, nullptr,
                                        nullptr, 10, 0, nullptr, info);
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_EQ(ret, SBA_ERROR);
    EXPECT_EQ(info[6], 0);
    EXPECT_NE(err.find("too large for the int-sized sba 1.6 API"), std::string::npos) << err;
  }
}

// Every product of sizes that an int offset holds, at the first values beyond INT_MAX: 2^31
// (or the next square), where an int product turns negative, and 2^32, where it wraps to 0
// and slips past a check made in int (a 2^20 x 4096 Jacobian block did, and the solve then
// wrote through a null Jacobian). Each call runs in a child whose address space may grow by
// no more than 256 MiB: the refusal must come before anything of that size is allocated or
// read, and name the product.
TEST(Faults, EverySizeProductThatWrapsAnIntIsRefusedBeforeAnythingIsAllocated) {
  enum Api { MotStrX, MotX, StrX, MotStrVis };
  struct Big {
    Api api;
    int n, m, cnp, pnp, mnp;
    long visible;  // the first `visible` cells of vmask (or pairs) are set
    bool covx;
    const char *expr;  // the product the message must name ...
    long long value;   // ... and its value
  };
  const long long k31 = 1LL << 31, k32 = 1LL << 32;
  std::vector<Big> cases;
  // A projection's Jacobian block, mnp*(cnp+pnp), over several splits of the factors.
  for (int s : {2, 10, 20, 29}) {
    cases.push_back({MotStrX, 1, 1, 1 << (30 - s), 1 << (30 - s), 1 << s, 1, false, "mnp*(cnp+pnp)", k31});
    cases.push_back({MotStrX, 1, 1, 1 << (31 - s), 1 << (31 - s), 1 << s, 1, false, "mnp*(cnp+pnp)", k32});
    cases.push_back({StrX, 1, 1, 0, 1 << (31 - s), 1 << s, 1, false, "mnp*(cnp+pnp)", k31});
    cases.push_back({StrX, 1, 1, 0, 1 << (32 - s), 1 << s, 1, false, "mnp*(cnp+pnp)", k32});
    cases.push_back({MotX, 1, 1, 1 << (31 - s), 0, 1 << s, 1, false, "mnp*(cnp+pnp)", k31});
    cases.push_back({MotX, 1, 1, 1 << (32 - s), 0, 1 << s, 1, false, "mnp*(cnp+pnp)", k32});
    cases.push_back({MotStrVis, 1, 1, 1 << (31 - s), 1 << (31 - s), 1 << s, 1, false, "mnp*(cnp+pnp)", k32});
  }
  // The reproducers: 2^20 x (2048 + 2048), and the structure-only 2^20 x 4096.
  cases.push_back({MotStrX, 1, 1, 2048, 2048, 1 << 20, 1, false, "mnp*(cnp+pnp)", k32});
  cases.push_back({StrX, 1, 1, 0, 4096, 1 << 20, 1, false, "mnp*(cnp+pnp)", k32});
  // Camera and point blocks U_j, V_i: the first square beyond INT_MAX, and 2^32.
  for (int c : {46341, 65536}) {
    const long long sq = (long long)c * c;
    cases.push_back({MotStrX, 1, 1, c, 3, 1, 1, false, "cnp*cnp", sq});
    cases.push_back({MotX, 1, 1, c, 0, 1, 1, false, "cnp*cnp", sq});
    cases.push_back({MotStrX, 1, 1, 6, c, 1, 1, false, "pnp*pnp", sq});
    cases.push_back({StrX, 1, 1, 0, c, 1, 1, false, "pnp*pnp", sq});
    cases.push_back({MotStrVis, 1, 1, 6, c, 1, 1, false, "pnp*pnp", sq});
    // A measurement's covariance block, when covx is given.
    cases.push_back({MotStrX, 1, 1, 1, 1, c, 1, true, "mnp*mnp", sq});
    cases.push_back({MotStrVis, 1, 1, 1, 1, c, 1, true, "mnp*mnp", sq});
  }
  // The parameter vector: all cameras, all points, and both together.
  cases.push_back({MotX, 1, 1 << 21, 1 << 10, 0, 2, 1, false, "m*cnp", k31});
  cases.push_back({MotX, 1, 1 << 21, 1 << 11, 0, 2, 1, false, "m*cnp", k32});
  cases.push_back({MotStrX, 1 << 21, 1, 6, 1 << 10, 2, 1, false, "n*pnp", k31});
  cases.push_back({StrX, 1 << 21, 1, 0, 1 << 11, 2, 1, false, "n*pnp", k32});
  cases.push_back({MotStrX, 46341, 1, 46340, 46340, 1, 1, false, "m*cnp+n*pnp",
                   46340LL + 46341LL * 46340});
  // x and hx (nvis*mnp), the whole Jacobian, and covx (nvis*mnp*mnp).
  cases.push_back({MotX, 1 << 11, 1, 1, 0, 1 << 20, 1 << 11, false, "nvis*mnp", k31});
  cases.push_back({MotX, 1 << 11, 1, 1, 0, 1 << 21, 1 << 11, false, "nvis*mnp", k32});
  cases.push_back({MotStrX, 1 << 10, 1, 1 << 10, 1 << 10, 1 << 10, 1 << 10, false, "nvis*mnp*(cnp+pnp)", k31});
  cases.push_back({MotStrX, 1 << 10, 1, 1 << 11, 1 << 11, 1 << 10, 1 << 10, false, "nvis*mnp*(cnp+pnp)", k32});
  cases.push_back({MotX, 1 << 11, 1, 1, 0, 1 << 10, 1 << 11, true, "nvis*mnp*mnp", k31});
  cases.push_back({MotX, 1 << 10, 1, 1, 0, 1 << 11, 1 << 10, true, "nvis*mnp*mnp", k32});

  for (const Big &b : cases) {
    // p and x as long as the problem needs when that is a few MiB (so that a solve that gets
    // past the checks runs into the wrapped Jacobian, as the reproducers did), else
    // far shorter: nothing may be read past them.
    const long long nvars = (long long)b.m * b.cnp + (long long)b.n * b.pnp;
    const long long nobs = (long long)b.visible * b.mnp;
    std::vector<double> p(size_t(nvars <= (1 << 20) ? std::max(nvars, 64LL) : 64), 1.0);
    std::vector<double> x(size_t(nobs <= (1 << 20) ? std::max(nobs, 64LL) : 64), 1.0);
    std::vector<double> covx(64, 0.0);
    const std::string label = std::string(b.expr) + " = " + std::to_string(b.value) + " (n " +
                              std::to_string(b.n) + ", m " + std::to_string(b.m) + ", cnp " +
                              std::to_string(b.cnp) + ", pnp " + std::to_string(b.pnp) + ", mnp " +
                              std::to_string(b.mnp) + ", api " + std::to_string(int(b.api)) + ")";
    SCOPED_TRACE(label);
    std::vector<char> vmask(size_t(b.n) * size_t(b.m), 0);
    std::fill(vmask.begin(), vmask.begin() + b.visible, 1);
    std::vector<int> pt(size_t(b.visible)), cam(size_t(b.visible));
    for (long k = 0; k < b.visible; ++k) pt[size_t(k)] = int(k / b.m), cam[size_t(k)] = int(k % b.m);
    const sba_visibility vis{b.visible, pt.data(), cam.data()};
    const long limit = address_space_bytes() + (256L << 20);
    const ChildOutcome out = run_in_child(
        [&](int fd) {
#ifndef SBA_TEST_SANITIZED
          const rlimit lim{rlim_t(limit), rlim_t(limit)};
          setrlimit(RLIMIT_AS, &lim);
#endif
          Report r;
          double *cv = b.covx ? covx.data() : nullptr;
          switch (b.api) {
            case MotStrX:
              r.ret = sba_motstr_levmar_x(b.n, 0, b.m, 0, vmask.data(), p.data(), b.cnp, b.pnp, x.data(),
                                          cv, b.mnp, synth::func_motstr, nullptr, nullptr, 10, 0,
                                          nullptr, r.info);
              break;
            case MotX:
              r.ret = sba_mot_levmar_x(b.n, b.m, 0, vmask.data(), p.data(), b.cnp, x.data(), cv, b.mnp,
                                       synth::func_motstr, nullptr, nullptr, 10, 0, nullptr, r.info);
              break;
            case StrX:
              r.ret = sba_str_levmar_x(b.n, 0, b.m, vmask.data(), p.data(), b.pnp, x.data(), cv, b.mnp,
                                       synth::func_motstr, nullptr, nullptr, 10, 0, nullptr, r.info);
              break;
            case MotStrVis:
              r.ret = sba_motstr_levmar_x_vis(b.n, 0, b.m, 0, &vis, p.data(), b.cnp, b.pnp, x.data(), cv,
                                              b.mnp, synth::func_motstr, nullptr, nullptr, 10, 0,
                                              nullptr, r.info, nullptr);
              break;
          }
          send(fd, r);
          return 0;
        },
        60);
    Report r;
    ASSERT_TRUE(out.exited && out.code == 0 && receive(out, &r)) << out.describe();
    EXPECT_EQ(r.ret, SBA_ERROR);
    EXPECT_EQ(r.info[6], 0);
    const std::string want = std::string(b.expr) + " = " + std::to_string(b.value) + ") exceeds INT_MAX";
    EXPECT_NE(out.err.find(want), std::string::npos) << out.err;
    EXPECT_EQ(std::count(out.err.begin(), out.err.end(), '\n'), 1) << out.err;
  }
}

// n*m itself beyond 2^31 is fine: vmask is indexed in 64 bits. A 2^16-point, 2^15+1-camera
// vmask (2 GiB, mapped without being backed) with a real 30-point, 4-camera problem in its
// last rows and columns, everything else fixed: the solve must find the same minimum as the
// same problem alone.
struct Embedded {
  int n = 1 << 16, m = (1 << 15) + 1;
  int n0 = 30, m0 = 4;  // the real problem
};

TEST(Faults, VmaskBeyondTwoGigabytesIsIndexedIn64Bits) {
  const Embedded e;
  ASSERT_GT(double(e.n) * e.m, double(std::numeric_limits<int>::max()));
  synth::Problem pb = synth::make(e.n0, e.m0, 0.3, 0.05, 107);
  // The small problem alone.
  std::vector<double> ps = pb.p0;
  double info_s[SBA_INFOSZ];
  const int rs = sba_motstr_levmar_x(pb.n, 0, pb.m, 0, pb.vmask.data(), ps.data(), kCnp, kPnp,
                                     pb.x.data(), nullptr, kMnp, synth::func_motstr,
                                     synth::fjac_motstr, &pb, 100, 0, nullptr, info_s);
  ASSERT_GT(rs, 0);

  const size_t cells = size_t(e.n) * size_t(e.m);
  void *mem = mmap(nullptr, cells, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  if (mem == MAP_FAILED) GTEST_SKIP() << "cannot map 2 GiB of address space for the vmask";
  char *vmask = static_cast<char *>(mem);
  const int i0 = e.n - e.n0, j0 = e.m - e.m0;
  for (int i = 0; i < e.n0; ++i)
    for (int j = 0; j < e.m0; ++j) vmask[size_t(i0 + i) * e.m + size_t(j0 + j)] = pb.vmask[size_t(i) * e.m0 + j];
  // p: every other camera and point somewhere harmless (they are fixed).
  std::vector<double> p(size_t(e.m) * kCnp + size_t(e.n) * kPnp, 0.0);
  for (int j = 0; j < e.m; ++j) p[size_t(j) * kCnp + 5] = 6.0;
  std::copy(pb.p0.begin(), pb.p0.begin() + e.m0 * kCnp, p.begin() + long(j0) * kCnp);
  std::copy(pb.p0.begin() + e.m0 * kCnp, pb.p0.end(), p.begin() + long(e.m) * kCnp + long(i0) * kPnp);
  struct Ctx {
    synth::Problem *pb;
    int i0, j0, m;
  } ctx{&pb, i0, j0, e.m};
  // Callbacks over the big index: only the visible pairs are evaluated, all in the corner.
  auto func = [](double *pp, sba_crsm *idx, int *, int *, double *hx, void *ad) {
    const Ctx &c = *static_cast<Ctx *>(ad);
    for (int i = 0; i < idx->nr; ++i)
      for (int k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k)
        synth::project(pp + size_t(idx->colidx[k]) * kCnp, pp + size_t(c.m) * kCnp + size_t(i) * kPnp,
                       hx + size_t(idx->val[k]) * kMnp, nullptr, nullptr);
  };
  auto fjac = [](double *pp, sba_crsm *idx, int *, int *, double *jac, void *ad) {
    const Ctx &c = *static_cast<Ctx *>(ad);
    double xx[2];
    for (int i = 0; i < idx->nr; ++i)
      for (int k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k) {
        double *blk = jac + size_t(idx->val[k]) * kMnp * (kCnp + kPnp);
        synth::project(pp + size_t(idx->colidx[k]) * kCnp, pp + size_t(c.m) * kCnp + size_t(i) * kPnp,
                       xx, blk, blk + kMnp * kCnp);
      }
  };
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = "sparse-chol";
  ext.nthreads = 1;
  double info[SBA_INFOSZ];
  const int r = sba_motstr_levmar_x_ext(e.n, i0, e.m, j0, vmask, p.data(), kCnp, kPnp, pb.x.data(),
                                        nullptr, kMnp, func, fjac, &ctx, 100, 0, nullptr, info, &ext);
  munmap(mem, cells);
  ASSERT_GT(r, 0);
  // The gauge is fixed differently (mcon/ncon fix nothing of the small problem), so the
  // minima agree in error, not necessarily in parameters.
  EXPECT_NEAR(info[0], info_s[0], 1e-9 * info_s[0]);
  EXPECT_NEAR(info[1], info_s[1], 1e-6 * info_s[1]);
}

// ---------------------------------------------------------------- every bad argument, every driver

struct BadCase {
  const char *what;
  std::function<bool(Driver)> applies;
  std::function<void(Driver, Rig &, Call &, std::vector<char> &, std::vector<double> &)> spoil;
  const char *expect;  // in the message
};

TEST(Faults, EveryDriverRefusesEveryBadArgumentWithOneLineNamingIt) {
  auto all = [](Driver) { return true; };
  static constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  static constexpr double inf = std::numeric_limits<double>::infinity();
  static const double bad_opts[SBA_OPTSSZ] = {1e-3, 1e-12, nan, 1e-12, 0.0};
  const std::vector<BadCase> cases = {
      {"n = 0", all, [](Driver, Rig &, Call &c, auto &, auto &) { c.n = 0; }, "n must be positive (got 0)"},
      {"n < 0", all, [](Driver, Rig &, Call &c, auto &, auto &) { c.n = -5; }, "n must be positive (got -5)"},
      {"m = 0", all, [](Driver, Rig &, Call &c, auto &, auto &) { c.m = 0; }, "m must be positive (got 0)"},
      {"m < 0", all, [](Driver, Rig &, Call &c, auto &, auto &) { c.m = -1; }, "m must be positive (got -1)"},
      {"cnp = 0", has_cameras, [](Driver, Rig &, Call &c, auto &, auto &) { c.cnp = 0; }, "cnp must be positive"},
      {"cnp < 0", has_cameras, [](Driver, Rig &, Call &c, auto &, auto &) { c.cnp = -6; }, "cnp must be positive"},
      {"pnp = 0", has_points, [](Driver, Rig &, Call &c, auto &, auto &) { c.pnp = 0; }, "pnp must be positive"},
      {"pnp < 0", has_points, [](Driver, Rig &, Call &c, auto &, auto &) { c.pnp = -3; }, "pnp must be positive"},
      {"mnp = 0", all, [](Driver, Rig &, Call &c, auto &, auto &) { c.mnp = 0; }, "mnp must be positive"},
      {"mnp < 0", all, [](Driver, Rig &, Call &c, auto &, auto &) { c.mnp = -2; }, "mnp must be positive"},
      {"mcon < 0", has_cameras, [](Driver, Rig &, Call &c, auto &, auto &) { c.mcon = -1; }, "mcon must be in [0, m]"},
      {"mcon > m", has_cameras, [](Driver, Rig &, Call &c, auto &, auto &) { c.mcon = c.m + 1; }, "mcon must be in [0, m]"},
      {"ncon < 0", has_points, [](Driver, Rig &, Call &c, auto &, auto &) { c.ncon = -1; }, "ncon must be in [0, n]"},
      {"ncon > n", has_points, [](Driver, Rig &, Call &c, auto &, auto &) { c.ncon = c.n + 1; }, "ncon must be in [0, n]"},
      {"everything fixed", all,
       [](Driver d, Rig &, Call &c, auto &, auto &) {
         if (has_cameras(d)) c.mcon = c.m;
         if (has_points(d)) c.ncon = c.n;
       },
       "nothing to refine"},
      {"vmask NULL", all, [](Driver, Rig &, Call &c, auto &, auto &) { c.vmask = nullptr; }, "vmask is NULL"},
      {"p NULL", all, [](Driver, Rig &, Call &c, auto &, auto &) { c.p = nullptr; }, "p is NULL"},
      {"x NULL", all, [](Driver, Rig &, Call &c, auto &, auto &) { c.x = nullptr; }, "x is NULL"},
      {"func NULL", all, [](Driver, Rig &, Call &c, auto &, auto &) { c.func = false; },
       "the projection function (func or proj) is NULL"},
      {"itmax < 0", all, [](Driver, Rig &, Call &c, auto &, auto &) { c.itmax = -1; }, "itmax must be >= 0"},
      {"opts NaN", all, [](Driver, Rig &, Call &c, auto &, auto &) { c.opts = bad_opts; }, "opts[2] is not finite"},
      {"all-zero vmask", all,
       [](Driver, Rig &, Call &c, std::vector<char> &vm, auto &) {
         std::fill(vm.begin(), vm.end(), 0);
         c.vmask = vm.data();
       },
       "no visible projection"},
      {"fewer measurements than parameters", all,
       [](Driver, Rig &, Call &c, std::vector<char> &vm, auto &) {
         std::fill(vm.begin(), vm.end(), 0);
         vm[0] = vm[1] = 1;  // 4 measurements
         c.vmask = vm.data();
       },
       "fewer measurements (4) than free parameters"},
      {"NaN in p", all,
       [](Driver, Rig &su, Call &c, auto &, std::vector<double> &v) {
         v = su.p;
         v[4] = nan;
         c.p = v.data();
       },
       "p[4] is not finite"},
      {"-Inf in p", all,
       [](Driver, Rig &su, Call &c, auto &, std::vector<double> &v) {
         v = su.p;
         v[v.size() - 1] = -inf;
         c.p = v.data();
       },
       "] is not finite"},
      {"Inf in x", all,
       [](Driver, Rig &su, Call &c, auto &, std::vector<double> &v) {
         v = su.pb.x;
         v[7] = inf;
         c.x = v.data();
       },
       "x[7] is not finite"},
      {"NaN in covx", all,
       [](Driver, Rig &su, Call &c, auto &, std::vector<double> &v) {
         v = su.covx;
         v[9] = nan;
         c.covx = v.data();
       },
       "covx[9] is not finite"},
      {"covx not positive definite", all,
       [](Driver, Rig &su, Call &c, auto &, std::vector<double> &v) {
         v = su.covx;
         v[4 * 3 + 1] = v[4 * 3 + 2] = 2.0;  // [1 2; 2 1] is indefinite
         c.covx = v.data();
       },
       "covariance of measurement 3"},
      {"covx not symmetric", all,
       [](Driver, Rig &su, Call &c, auto &, std::vector<double> &v) {
         v = su.covx;
         v[4 * 6 + 1] = 0.5;  // [1 0.5; 0 1]
         c.covx = v.data();
       },
       "covariance of measurement 6"},
  };
  for (Driver d : kAllDrivers) {
    Rig su(d, 20, 3, 0.0, 108);
    {
      Call good = su.base();
      good.covx = su.covx.data();
      ASSERT_GT(call(d, good, &su.sab), 0) << name_of(d) << ": the unspoilt call must work";
      su.p = su.p0;
    }
    for (const BadCase &bc : cases) {
      if (!bc.applies(d)) continue;
      SCOPED_TRACE(std::string(name_of(d)) + ": " + bc.what);
      std::vector<char> vm = su.pb.vmask;
      std::vector<double> scratch;
      Call c = su.base();
      bc.spoil(d, su, c, vm, scratch);
      std::fill(su.info, su.info + SBA_INFOSZ, -42.0);
      su.sab.reset();
      testing::internal::CaptureStdout();
      testing::internal::CaptureStderr();
      const int ret = call(d, c, &su.sab);
      const std::string err = testing::internal::GetCapturedStderr();
      const std::string out = testing::internal::GetCapturedStdout();
      EXPECT_EQ(ret, SBA_ERROR);
      EXPECT_NE(err.find(bc.expect), std::string::npos) << err;
      // One line, naming the driver (covariance problems are found by the core, which names
      // the library).
      EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
      EXPECT_TRUE(err.rfind(std::string(name_of(d)) + ": ", 0) == 0 || err.rfind("sba: ", 0) == 0) << err;
      EXPECT_EQ(out, "");
      EXPECT_EQ(su.info[6], 0);  // filled: nothing ran
      EXPECT_EQ(su.info[5], 0);
      EXPECT_EQ(su.p, su.p0);
      EXPECT_EQ(su.sab.jac_calls, 0);
    }
  }
}

}  // namespace
