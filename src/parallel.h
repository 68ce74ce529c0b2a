/* SPDX-License-Identifier: BSD-3-Clause */
// A small thread pool owned by one solve (no global state) and helpers for deterministic
// parallel loops: work is split into ranges that do not depend on the thread count where
// results are summed, so that any number of threads gives the same bits.
#ifndef SBA_SRC_PARALLEL_H
#define SBA_SRC_PARALLEL_H

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace sba {

class ThreadPool {
 public:
  // nthreads - 1 workers; the calling thread is the last member. If the system refuses
  // threads, the pool makes do with those it got. avoid_shared_cores: see avoid_shared_core
  // in parallel.cpp; off, no thread's CPU mask is ever touched.
  explicit ThreadPool(int nthreads, bool avoid_shared_cores = false);
  ~ThreadPool();
  ThreadPool(const ThreadPool &) = delete;
  ThreadPool &operator=(const ThreadPool &) = delete;

  int size() const { return int(workers_.size()) + 1; }
  // fn(t) for every t in [0, size()), concurrently; returns when all are done. A worker's
  // fn(t) that it has not begun by the time the caller is done with its own runs in the
  // calling thread instead, so fn(t) must not depend on the thread that runs it (only on t),
  // and may wait for another member (a SpinBarrier) only where every member waits. The first
  // exception thrown by any of them is rethrown here. A forced unwind (a thread ended by
  // pthread_exit or pthread_cancel inside fn) is let through in the thread it ends: in the
  // calling thread once the workers are done with fn; in a worker, which then ends, as
  // std::runtime_error here, and every later run() throws it at once (the pool is short of
  // a member).
  void run(const std::function<void(int)> &fn);

  // A job whose members wait for each other (SpinBarrier) runs at the pace of the member
  // that last got a core: on a machine busier than its cores, every barrier can wait
  // milliseconds for a member the scheduler has set aside while the others spin, and the
  // caller cannot take over a part that has begun. Such a kernel runs on every member only
  // when together() says so, and then tells waited() how long its caller's part spent at
  // the barriers; after two jobs in a row that were mostly waiting (one alone can be the
  // workers' first wake-up), the next ones run on one thread for a while, and for twice as
  // long each time it happens again without a good job between. Both are called by the
  // caller, between jobs.
  bool together();
  void waited(double barrier_seconds, double job_seconds);
  // The jobs handed to the workers so far.
  std::uint64_t jobs() const { return generation_.load(std::memory_order_relaxed); }

  // For its lifetime the workers sleep instead of spinning for the next job: made around a
  // long call into another library (LAPACK, CHOLMOD) that runs its own threads, so that our
  // spinning workers do not take the cores those threads need.
  class ForeignThreads {
   public:
    explicit ForeignThreads(ThreadPool &pool) : pool_(pool) {
      pool_.resting_.store(true, std::memory_order_release);
    }
    ~ForeignThreads() { pool_.resting_.store(false, std::memory_order_release); }
    ForeignThreads(const ForeignThreads &) = delete;
    ForeignThreads &operator=(const ForeignThreads &) = delete;

   private:
    ThreadPool &pool_;
  };

  // fn(t, begin, end) over [0, n) in size() contiguous ranges, t the range's thread slot.
  template <class Fn>
  void for_range_t(std::int64_t n, Fn fn) {
    const int T = size();
    if (T == 1 || n < 2) {
      if (n > 0) fn(0, std::int64_t(0), n);
      return;
    }
    run([&](int t) {
      const std::int64_t b = n * t / T, e = n * (t + 1) / T;
      if (b < e) fn(t, b, e);
    });
  }

  // fn(t, begin, end) -> bool as for_range_t; true when every call returned true. A range
  // may stop at its first failure; the others still run to their end.
  template <class Fn>
  bool all_ranges(std::int64_t n, Fn fn) {
    std::vector<int> ok(size_t(size()), 1);
    for_range_t(n, [&](int t, std::int64_t b, std::int64_t e) { ok[size_t(t)] = fn(t, b, e); });
    return all_true(ok);
  }

  // fn(t) -> bool for every member as run() (or for member 0 alone when `alone`); true when
  // every call returned true.
  template <class Fn>
  bool all_members(Fn fn, bool alone = false) {
    std::vector<int> ok(size_t(size()), 1);
    if (alone || size() == 1)
      ok[0] = fn(0);
    else
      run([&](int t) { ok[size_t(t)] = fn(t); });
    return all_true(ok);
  }

  // fn(begin, end) over [0, n) in size() contiguous ranges.
  template <class Fn>
  void for_range(std::int64_t n, Fn fn) {
    if (size() == 1 || n < 2) {
      if (n > 0) fn(std::int64_t(0), n);
      return;
    }
    const int T = size();
    run([&](int t) {
      const std::int64_t b = n * t / T, e = n * (t + 1) / T;
      if (b < e) fn(b, e);
    });
  }

 private:
  static bool all_true(const std::vector<int> &ok) {
    for (int c : ok)
      if (!c) return false;
    return true;
  }
  void work(int id);
  bool take(int id, std::uint64_t generation);
  void do_part(const std::function<void(int)> &job, int id, bool worker);
  void job_done();
  void wait_for_workers();
  void avoid_shared_core(int id, int *cooldown);

  std::vector<std::thread> workers_;
  // An LM iteration hands the pool a few dozen short jobs with a little serial work between
  // them. Waking a sleeping thread costs more than many of those jobs (on a virtual machine
  // especially), so both sides first spin for a while (kSpin) on the atomics below and
  // only then sleep on the condition variables.
  std::mutex mu_;
  std::condition_variable wake_, done_;
  const std::function<void(int)> *job_ = nullptr;  // published by generation_
  std::atomic<std::uint64_t> generation_{0};
  std::atomic<int> pending_{0};
  std::atomic<bool> stop_{false};
  std::atomic<bool> resting_{false};
  std::atomic<bool> lost_worker_{false};  // a worker was ended by a forced unwind
  // By worker: the last generation whose part was taken, by the worker or by the caller.
  std::unique_ptr<std::atomic<std::uint64_t>[]> taken_;
  std::exception_ptr error_;  // guarded by mu_
  const bool avoid_shared_cores_;
  // together(): the jobs still to run alone, how many the next backing off sends there, and
  // the mostly waiting jobs in a row.
  int alone_ = 0;
  int strikes_ = 0;
  int backoff_ = kFirstBackoff;
  static constexpr int kFirstBackoff = 16, kMaxBackoff = 1024;
  // The CPU each member last ran a job on (the caller's: last), -1 if unknown; kept only
  // when avoid_shared_cores_.
  std::unique_ptr<std::atomic<int>[]> cpu_;
};

// A barrier for the threads of one ThreadPool::run job, for kernels whose short phases depend
// on each other (a new run() per phase costs a mutex and a wake-up each). Waiters spin,
// yielding the core now and then so that a descheduled member still gets to arrive.
class SpinBarrier {
 public:
  explicit SpinBarrier(int n) : n_(n) {}
  void wait() {
    const unsigned gen = generation_.load(std::memory_order_acquire);
    if (count_.fetch_add(1, std::memory_order_acq_rel) + 1 == n_) {
      count_.store(0, std::memory_order_relaxed);
      generation_.store(gen + 1, std::memory_order_release);
      return;
    }
    for (int k = 1; generation_.load(std::memory_order_acquire) == gen; ++k) {
#if defined(__x86_64__) || defined(__i386__)
      __builtin_ia32_pause();
#endif
      if (k % 64 == 0) std::this_thread::yield();
    }
  }
  // wait(), adding the seconds it took to *spent.
  void wait(double *spent) {
    const auto start = std::chrono::steady_clock::now();
    wait();
    *spent += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }

 private:
  const int n_;
  std::atomic<int> count_{0};
  std::atomic<unsigned> generation_{0};
};

// The first 64-byte aligned double at or after p (a buffer allocated with 7 doubles to
// spare): data that two threads write in neighbouring parts starts on a cache line, so that
// where their parts meet on a line boundary they never write the same line.
inline double *align_to_line(double *p) {
  const auto addr = reinterpret_cast<std::uintptr_t>(p);
  return p + ((64 - addr % 64) % 64) / sizeof(double);
}

// The sums of the kBlock-long blocks b .. b + C - 1 of f into partial, each block's a chain of
// additions in ascending order. A chain waits for each addition before the next, so one block
// at a time runs at the adder's latency; C chains side by side fill its pipeline, and each
// block's sum keeps the bits it has alone.
template <int C, class F>
inline void block_sums(std::int64_t b, std::int64_t block, F &f, double *partial) {
  double s[C] = {};
  for (std::int64_t k = 0; k < block; ++k)
#pragma GCC unroll 8
    for (int c = 0; c < C; ++c) s[c] += f((b + c) * block + k);
  for (int c = 0; c < C; ++c) partial[b + c] = s[c];
}

// sum_k f(k) over [0, n), summed in fixed blocks and then in block order: the same bits for
// any thread count.
template <class F>
double deterministic_sum(ThreadPool &pool, std::int64_t n, F f) {
  constexpr std::int64_t kBlock = 4096;
  const std::int64_t nb = (n + kBlock - 1) / kBlock;
  std::vector<double> partial(size_t(nb > 0 ? nb : 0), 0.0);
  pool.for_range(nb, [&](std::int64_t b0, std::int64_t b1) {
    // Whole blocks eight, four or two at a time; the rest (the last block may be shorter)
    // one at a time.
    const std::int64_t whole = std::min(b1, n / kBlock);
    std::int64_t b = b0;
    for (; b + 8 <= whole; b += 8) block_sums<8>(b, kBlock, f, partial.data());
    if (b + 4 <= whole) block_sums<4>(b, kBlock, f, partial.data()), b += 4;
    if (b + 2 <= whole) block_sums<2>(b, kBlock, f, partial.data()), b += 2;
    for (; b < b1; ++b) {
      double s = 0.0;
      const std::int64_t e = std::min(n, b * kBlock + kBlock);
      for (std::int64_t k = b * kBlock; k < e; ++k) s += f(k);
      partial[size_t(b)] = s;
    }
  });
  double s = 0.0;
  for (double v : partial) s += v;
  return s;
}

}  // namespace sba

#endif
