/* SPDX-License-Identifier: BSD-3-Clause */
// Stopping a solve from outside the library, the way the library offers: its progress
// callback, called after every iteration, returns nonzero and the solve ends cleanly there
// (info[6] = SBA_STOP_USER, p at the last accepted estimate). Two things ask for it:
// - SIGINT or SIGTERM: the first one asks the solve to stop, so that the program can still
//   print its summary and write its results; a second one ends the process at once, for a
//   user who will not wait for the iteration to end. A first one that comes after the solve
//   has ended stops nothing: the program abandons its files and ends as the signal asked
//   (late_signal). A signal the program was started with ignored stays ignored (a background
//   job of a script), and at exit the signals are the system's again.
// - a time limit (--max-time), checked after each iteration.
// It also keeps the error and time of every iteration, for --json. A covariance computed after
// the solve (eucsbademo --write-stddev) has no iterations: a stop signal abandons it through the
// library's cancel callback instead (attach_cancel).
#ifndef SBA_DEMO_RUN_CONTROL_H
#define SBA_DEMO_RUN_CONTROL_H

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <vector>

#include "cli/tty_progress.h"
#include "formats/output_file.h"
#include "sba_ext.h"

namespace sbacli {

// The first stop signal received (0: none). A signal handler can only talk to the program
// through such a flag, so it is the one piece of global state the programs keep, with the
// line the second signal prints (set before the handler is installed, read-only after).
inline volatile std::sig_atomic_t g_stop_signal = 0;
inline char g_second_signal_line[96] = "";

extern "C" inline void on_stop_signal(int sig) {
  if (g_stop_signal != 0) {  // the second signal: at once, with only async-signal-safe calls
    const ssize_t said = write(STDERR_FILENO, g_second_signal_line, std::strlen(g_second_signal_line));
    (void)said;
    _exit(128 + sig);
  }
  g_stop_signal = sig;
}

class RunControl {
 public:
  struct Iteration {
    int solve;       // 0, or 1 for the second solve of a two-stage refinement
    int iteration;   // as sba_progress counts them
    double error;    // ||e||^2 (the robust cost with a loss)
    double seconds;  // since the RunControl was made
  };

  // max_seconds: the time limit from now (0: none). tty: the progress line to keep drawing
  // (may be null).
  RunControl(double max_seconds, TtyProgress *tty)
      : max_seconds_(max_seconds), tty_(tty), start_(std::chrono::steady_clock::now()) {}
  RunControl(const RunControl &) = delete;
  RunControl &operator=(const RunControl &) = delete;

  // SIGINT and SIGTERM stop the solve instead of the process (see above), unless ignored.
  static void catch_signals(const char *program) {
    std::snprintf(g_second_signal_line, sizeof g_second_signal_line, "%s: stopped at once by a second signal\n",
                  program);
    for (const int sig : {SIGINT, SIGTERM}) {
      struct sigaction old {};
      if (sigaction(sig, nullptr, &old) != 0 || old.sa_handler == SIG_IGN) continue;
      struct sigaction sa {};
      sa.sa_handler = on_stop_signal;
      sigemptyset(&sa.sa_mask);
      sa.sa_flags = SA_RESTART;
      sigaction(sig, &sa, nullptr);
    }
  }
  // The system's handling of SIGINT and SIGTERM again (where catch_signals took it): what is
  // left of the program (its exit) ends at a signal.
  static void release_signals() {
    for (const int sig : {SIGINT, SIGTERM}) {
      struct sigaction old {};
      if (sigaction(sig, nullptr, &old) != 0 || old.sa_handler != on_stop_signal) continue;
      struct sigaction sa {};
      sa.sa_handler = SIG_DFL;
      sigemptyset(&sa.sa_mask);
      sigaction(sig, &sa, nullptr);
    }
  }

  // Installs the progress callback for the next solve.
  void attach(sba_ext_options *ext) {
    ext->progress = &RunControl::callback;
    ext->progress_ctx = this;
  }
  // Installs the cancel callback of a covariance (sba_ext_options.cancel): a stop signal, even
  // one received before it started, abandons it, as pysba's Ctrl-C does. The time limit does
  // not: it bounds the solve, whose result the covariance describes.
  static void attach_cancel(sba_ext_options *ext) {
    ext->cancel = &RunControl::cancel;
    ext->cancel_ctx = nullptr;
  }
  // The next solve's iterations are counted as the second solve's.
  void next_solve() { ++solve_; }

  // Why the last solve was asked to stop, if it was.
  int stop_signal() const { return g_stop_signal; }
  const char *stop_signal_name() const { return g_stop_signal == SIGINT ? "SIGINT" : "SIGTERM"; }
  bool timed_out() const { return timed_out_; }
  bool stop_requested() const { return g_stop_signal != 0 || timed_out_; }
  // A stop signal that stopped nothing (solve_stopped false: it came once the computation had
  // ended) ends the run without its files: they are discarded, the signal is said on stderr,
  // and 128 + the signal is returned; 0 when there was no such signal.
  int late_signal(const char *program, bool solve_stopped, sbaformats::OutputSet *outputs) const {
    if (g_stop_signal == 0 || solve_stopped) return 0;
    outputs->discard();
    std::fprintf(stderr, "%s: interrupted by %s after the solve: no file written\n", program, stop_signal_name());
    return 128 + g_stop_signal;
  }
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }
  const std::vector<Iteration> &iterations() const { return iterations_; }

 private:
  static int callback(void *ctx, const sba_progress *s) {
    auto *self = static_cast<RunControl *>(ctx);
    const double t = self->seconds();
    self->iterations_.push_back({self->solve_, s->iteration, s->error, t});
    if (self->tty_) self->tty_->show(s);
    if (self->max_seconds_ > 0 && t >= self->max_seconds_) self->timed_out_ = true;
    return self->stop_requested() ? 1 : 0;
  }

  static int cancel(void *) { return g_stop_signal != 0 ? 1 : 0; }

  double max_seconds_;
  TtyProgress *tty_;
  std::chrono::steady_clock::time_point start_;
  int solve_ = 0;
  bool timed_out_ = false;
  std::vector<Iteration> iterations_;
};

}  // namespace sbacli

#endif  // SBA_DEMO_RUN_CONTROL_H
