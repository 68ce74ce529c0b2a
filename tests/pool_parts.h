/* SPDX-License-Identifier: BSD-3-Clause */
// For tests that need a part of a ThreadPool job to run on the worker's own thread.
#ifndef SBA_TESTS_POOL_PARTS_H
#define SBA_TESTS_POOL_PARTS_H

#include <atomic>
#include <thread>

#include "parallel.h"

// fn() as member 0's part of a job, in the worker's own thread: the others wait until it has
// begun, so that the caller, done with its part, does not take that one over. run() returns
// once fn() has; a signal pending for the worker is handled before its part begins.
template <class Fn>
void on_worker(sba::ThreadPool &pool, Fn fn) {
  std::atomic<bool> begun{false};
  pool.run([&](int t) {
    if (t == 0) {
      begun = true;
      fn();
    } else {
      while (!begun.load()) std::this_thread::yield();
    }
  });
}

#endif
