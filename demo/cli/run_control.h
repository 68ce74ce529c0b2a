/* SPDX-License-Identifier: BSD-3-Clause */
// Stopping a solve from outside the library, the way the library offers: its progress
// callback, called after every iteration, returns nonzero and the solve ends cleanly there
// (info[6] = SBA_STOP_USER, p at the last accepted estimate). Two things ask for it:
// - SIGINT or SIGTERM: the first one asks the solve to stop, so that the program can still
//   print its summary and write its results; a second one ends the process at once, for a
//   user who will not wait for the iteration to end.
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
#include <vector>

#include "cli/tty_progress.h"
#include "sba_ext.h"

namespace sbacli {

// The first stop signal received (0: none). A signal handler can only talk to the program
// through such a flag, so it is the one piece of global state the programs keep.
inline volatile std::sig_atomic_t g_stop_signal = 0;

extern "C" inline void on_stop_signal(int sig) {
  if (g_stop_signal != 0) _exit(128 + sig);  // the second signal: at once (async-signal-safe)
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

  // SIGINT and SIGTERM stop the solve instead of the process (see above).
  static void catch_signals() {
    struct sigaction sa {};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);
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
