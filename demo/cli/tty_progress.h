/* SPDX-License-Identifier: BSD-3-Clause */
// A one-line progress display for long solves, on stderr and only when stderr is a terminal
// (so that logs and pipes never see it): sba's progress callback rewrites the line in place.
#ifndef SBA_DEMO_TTY_PROGRESS_H
#define SBA_DEMO_TTY_PROGRESS_H

#include <unistd.h>

#include <cstdio>

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

}  // namespace sbacli

#endif
