/* SPDX-License-Identifier: BSD-3-Clause */
// A one-line progress display for long solves, on stderr and only when stderr is a terminal
// (so that logs and pipes never see it): sba's progress callback rewrites the line in place;
// and the same for the phases around them (TtyPhase).
#ifndef SBA_DEMO_TTY_PROGRESS_H
#define SBA_DEMO_TTY_PROGRESS_H

#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>
#include <utility>

#include "sba_ext.h"

namespace sbacli {

class TtyProgress {
 public:
  // enabled: the caller's wish (e.g. not --no-progress); the terminal test comes on top.
  // per_measurement: divides the error so that it reads like the demo's summary.
  TtyProgress(bool enabled, double per_measurement)
      : on_(enabled && isatty(STDERR_FILENO)), scale_(per_measurement > 0 ? 1.0 / per_measurement : 1.0) {}
  TtyProgress(const TtyProgress &) = delete;
  TtyProgress &operator=(const TtyProgress &) = delete;
  ~TtyProgress() { finish(); }

  // Installs itself as ext's progress callback (nothing when stderr is not a terminal).
  void attach(sba_ext_options *ext) {
    if (!on_) return;
    ext->progress = &TtyProgress::callback;
    ext->progress_ctx = this;
  }
  // Draws the line for s, for a caller whose own progress callback shows it too.
  void show(const sba_progress *s) {
    if (on_) callback(this, s);
  }
  // Ends the line, if one was drawn.
  void finish() {
    if (!drawn_) return;
    std::fputc('\n', stderr);
    std::fflush(stderr);
    drawn_ = false;
  }

 private:
  static int callback(void *ctx, const sba_progress *s) {
    auto *self = static_cast<TtyProgress *>(ctx);
    // Short runs finish before anyone would read a progress line; then at most ten a second.
    if (s->elapsed < 0.5 || s->elapsed - self->last_ < 0.1) return 0;
    self->last_ = s->elapsed;
    std::fprintf(stderr, "\r  iteration %d  error %.6g  mu %.3g  step %.3g  %.1f s   ", s->iteration,
                 s->error * self->scale_, s->mu, s->dp_norm, s->elapsed);
    std::fflush(stderr);
    self->drawn_ = true;
    return 0;
  }

  bool on_;
  double scale_;
  bool drawn_ = false;
  double last_ = 0.0;
};

// The same line for a phase of a program that has no iterations to show (reading or writing a
// large model): "  reading DIR" as the phase starts, then, from half a second on, the seconds
// it has taken, redrawn ten times a second by a thread of its own, since the phase's code has
// no progress to report. A phase that ends before half a second takes its line away again (a
// short run leaves nothing on the terminal); a longer one leaves it, with its time. Nothing
// else may write to stderr while it is on.
class TtyPhase {
 public:
  TtyPhase(bool enabled, std::string what)
      : on_(enabled && isatty(STDERR_FILENO)), what_(std::move(what)), start_(std::chrono::steady_clock::now()) {
    if (!on_) return;
    std::fprintf(stderr, "\r  %s", what_.c_str());
    std::fflush(stderr);
    ticker_ = std::thread([this] { tick(); });
  }
  TtyPhase(const TtyPhase &) = delete;
  TtyPhase &operator=(const TtyPhase &) = delete;
  ~TtyPhase() { end(); }

  // Ends the phase and its line (once).
  void end() {
    if (!on_) return;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_one();
    ticker_.join();
    on_ = false;
    if (seconds() < kShownAfter) {
      std::fputs("\r\033[K", stderr);  // back to the line's start, and the rest of it erased
    } else {
      draw();
      std::fputc('\n', stderr);
    }
    std::fflush(stderr);
  }

 private:
  static constexpr double kShownAfter = 0.5;  // as TtyProgress's iterations

  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }
  void draw() const { std::fprintf(stderr, "\r  %s  %.1f s   ", what_.c_str(), seconds()); }

  void tick() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!wake_.wait_for(lock, std::chrono::milliseconds(100), [this] { return stop_; }))
      if (seconds() >= kShownAfter) {
        draw();
        std::fflush(stderr);
      }
  }

  bool on_;
  std::string what_;
  std::chrono::steady_clock::time_point start_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;  // under mutex_
  std::thread ticker_;
};

}  // namespace sbacli

#endif
