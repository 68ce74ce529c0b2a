// SPDX-License-Identifier: BSD-3-Clause
#include "parallel.h"

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <system_error>

#include "forced_unwind.h"

#if defined(__linux__)
#include <sched.h>
#endif

namespace sba {

namespace {

// The CPU the calling thread runs on, or -1 where that cannot be known.
int current_cpu() {
#if defined(__linux__)
  return sched_getcpu();
#else
  return -1;
#endif
}

}  // namespace

ThreadPool::ThreadPool(int nthreads, bool avoid_shared_cores)
    : taken_(new std::atomic<std::uint64_t>[size_t(std::max(nthreads, 1))]),
      avoid_shared_cores_(avoid_shared_cores),
      cpu_(new std::atomic<int>[size_t(std::max(nthreads, 1))]) {
  for (int t = 0; t < std::max(nthreads, 1); ++t) {
    cpu_[t].store(-1, std::memory_order_relaxed);
    taken_[t].store(0, std::memory_order_relaxed);
  }
  for (int t = 1; t < nthreads; ++t) {
    try {
      workers_.emplace_back([this, t] { work(t - 1); });
    } catch (const std::system_error &) {
      break;  // fewer threads than asked: slower, never wrong
    }
  }
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_.store(true);
  }
  wake_.notify_all();
  for (std::thread &w : workers_) w.join();
}

namespace {

// How long a thread spins for the next job or for the others to finish before sleeping:
// long enough to cover the serial work between two jobs of an iteration, short enough that
// an idle solve (waiting on a callback, or finished) gives its cores back at once.
constexpr auto kSpin = std::chrono::microseconds(200);

inline void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#endif
}

// Spins until done() or kSpin has passed; true if done().
template <class Done>
bool spin_until(Done done) {
  const auto until = std::chrono::steady_clock::now() + kSpin;
  for (;;) {
    for (int k = 0; k < 64; ++k) {
      if (done()) return true;
      cpu_relax();
    }
    std::this_thread::yield();
    if (std::chrono::steady_clock::now() >= until) return done();
  }
}

}  // namespace

SBA_CATCHES_FORCED_UNWIND void ThreadPool::work(int id) {
  std::uint64_t seen = 0;
  int cooldown = 0;
  for (;;) {
    auto ready = [&] { return stop_.load(std::memory_order_acquire) ||
                              generation_.load(std::memory_order_acquire) != seen; };
    auto ready_or_resting = [&] { return ready() || resting_.load(std::memory_order_acquire); };
    if (!spin_until(ready_or_resting) || !ready()) {
      std::unique_lock<std::mutex> lock(mu_);
      wake_.wait(lock, ready);
    }
    if (stop_.load(std::memory_order_acquire)) return;
    seen = generation_.load(std::memory_order_acquire);
    // The caller may have done this part already (and even have begun the next job): then
    // job_ is not this generation's, and there is nothing to do or to report.
    if (!take(id, seen)) continue;
    const std::function<void(int)> *job = job_;
    if (avoid_shared_cores_) avoid_shared_core(id, &cooldown);
    do_part(*job, id, true);
  }
}

// Part id of job, counted done however it ends; the first exception of the job's parts is
// kept for run() to rethrow. A forced unwind (pthread_exit or pthread_cancel in a callback)
// is let through: the thread is being ended and must be let go. A worker's then also marks
// the pool short of a member: the caller, waiting for the job, is told by run(), which also
// refuses the later jobs that would wait for this member forever.
SBA_CATCHES_FORCED_UNWIND void ThreadPool::do_part(const std::function<void(int)> &job, int id, bool worker) {
  try {
    job(id);
  }
#if SBA_HAVE_FORCED_UNWIND
  catch (abi::__forced_unwind &) {
    if (worker) lost_worker_.store(true, std::memory_order_release);
    job_done();
    throw;
  }
#endif
  catch (...) {
    std::lock_guard<std::mutex> lock(mu_);
    if (!error_) error_ = std::current_exception();
  }
  job_done();
}

// Whether the part of worker id in job `generation` falls to the one asking (the worker or
// the caller): the first to ask gets it. A worker can ask for a job that is long over (it was
// descheduled after reading the generation, and the caller did its parts in that job and in
// later ones): the generations taken only grow, so such a late ask gets nothing and does not
// give the part of a later job away.
bool ThreadPool::take(int id, std::uint64_t generation) {
  std::uint64_t last = taken_[id].load(std::memory_order_acquire);
  while (last < generation)
    if (taken_[id].compare_exchange_weak(last, generation, std::memory_order_acq_rel, std::memory_order_acquire))
      return true;
  return false;
}

void ThreadPool::job_done() {
  if (pending_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
    // The lock orders this notify after a waiter's check of pending_ (no lost wake-up).
    std::lock_guard<std::mutex> lock(mu_);
    done_.notify_one();
  }
}

void ThreadPool::wait_for_workers() {
  auto finished = [&] { return pending_.load(std::memory_order_acquire) == 0; };
  if (!spin_until(finished)) {
    std::unique_lock<std::mutex> lock(mu_);
    done_.wait(lock, finished);
  }
}

// Only when the pool was made with avoid_shared_cores (sba_ext_options.avoid_shared_cores or
// SBA_AVOID_SHARED_CORES=1): scheduling is the host process's business, and a core that is
// free of this pool may be the one the host keeps for something else, so a library does not
// do this unasked.
// A thread that another wakes, or a new one, can be put on the waker's core when its own
// core looks busy: on a virtual machine an idle virtual CPU can (the host may have lent it
// out), and so does a core where OpenBLAS's idle workers spin, for a tenth of a second
// after OpenBLAS loads or last ran them (docs/threads.md). The caller and a worker then
// take turns on one core until the kernel's load balancer parts them, milliseconds later.
// So a worker that finds itself on the core of the caller or of a worker before it moves to
// a core that none of them uses, if its mask allows one: a short-lived affinity mask without
// the pool's cores makes the kernel move it at once, and its own mask put back lets it move
// freely again. Only the worker's own mask changes, never the caller's. Where there is no
// such core (more threads than cores), it looks again 64 jobs later.
void ThreadPool::avoid_shared_core(int id, int *cooldown) {
#if defined(__linux__)
  const int here = current_cpu(), T = size();
  cpu_[id].store(here, std::memory_order_relaxed);
  if (here < 0 || here >= CPU_SETSIZE) return;
  if (*cooldown > 0) {
    --*cooldown;
    return;
  }
  bool shared = false;
  for (int t = 0; t < T; ++t)
    if ((t < id || t == T - 1) && cpu_[t].load(std::memory_order_relaxed) == here) shared = true;
  if (!shared) return;
  cpu_set_t mask, elsewhere;
  if (sched_getaffinity(0, sizeof mask, &mask) != 0) return;
  elsewhere = mask;
  for (int t = 0; t < T; ++t) {
    const int c = cpu_[t].load(std::memory_order_relaxed);
    if (c >= 0 && c < CPU_SETSIZE) CPU_CLR(c, &elsewhere);
  }
  if (CPU_COUNT(&elsewhere) == 0 || sched_setaffinity(0, sizeof elsewhere, &elsewhere) != 0) {
    *cooldown = 64;
    return;
  }
  sched_setaffinity(0, sizeof mask, &mask);
  cpu_[id].store(current_cpu(), std::memory_order_relaxed);
#else
  (void)id;
  (void)cooldown;
#endif
}

bool ThreadPool::together() {
  if (workers_.empty()) return false;
  if (alone_ == 0) return true;
  --alone_;
  return false;
}

// On cores of the job's own, the caller waits at a barrier for the imbalance of a phase
// (near the smallest sizes run on several threads, up to about half the job); a member that
// lost its core costs a scheduler's time slice per barrier, many times a phase, and the
// caller waits nearly all the job. Three quarters lies between.
void ThreadPool::waited(double barrier_seconds, double job_seconds) {
  if (barrier_seconds <= 0.75 * job_seconds) {
    strikes_ = 0;
    backoff_ = kFirstBackoff;
  } else if (++strikes_ == 2) {
    strikes_ = 0;
    alone_ = backoff_;
    backoff_ = std::min(2 * backoff_, kMaxBackoff);
  }
}

namespace {

[[noreturn]] void throw_lost_worker() {
  throw std::runtime_error("a worker thread of the solve was ended (pthread_exit or pthread_cancel in a callback)");
}

}  // namespace

SBA_CATCHES_FORCED_UNWIND void ThreadPool::run(const std::function<void(int)> &fn) {
  if (workers_.empty()) {
    fn(0);
    return;
  }
  if (lost_worker_.load(std::memory_order_acquire)) throw_lost_worker();
  job_ = &fn;
  if (avoid_shared_cores_) cpu_[size() - 1].store(current_cpu(), std::memory_order_relaxed);
  pending_.store(int(workers_.size()), std::memory_order_relaxed);
  std::uint64_t generation;
  {
    std::lock_guard<std::mutex> lock(mu_);
    error_ = nullptr;
    generation = generation_.fetch_add(1, std::memory_order_release) + 1;
  }
  wake_.notify_all();
  std::exception_ptr mine;
  try {
    fn(size() - 1);
    // The parts of workers that have not begun theirs yet are done here rather than waited
    // for: on a machine busier than its cores, a woken worker can wait milliseconds for one,
    // many times a job's length, and a solve runs thousands of jobs.
    for (int w = 0; w < int(workers_.size()); ++w)
      if (take(w, generation)) do_part(fn, w, false);
  }
#if SBA_HAVE_FORCED_UNWIND
  catch (abi::__forced_unwind &) {
    // The calling thread is being ended. The workers are still running fn, whose captures
    // live in the frames this unwind is about to free: it goes on once they are done.
    wait_for_workers();
    throw;
  }
#endif
  catch (...) {
    mine = std::current_exception();
  }
  wait_for_workers();
  if (mine) std::rethrow_exception(mine);
  if (lost_worker_.load(std::memory_order_acquire)) throw_lost_worker();
  std::exception_ptr err;
  {
    std::lock_guard<std::mutex> lock(mu_);
    err = error_;
  }
  if (err) std::rethrow_exception(err);
}

}  // namespace sba
