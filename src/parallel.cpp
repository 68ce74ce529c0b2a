#include "parallel.h"

#include <chrono>
#include <system_error>

namespace sba {

ThreadPool::ThreadPool(int nthreads) {
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

void ThreadPool::work(int id) {
  std::uint64_t seen = 0;
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
    const std::function<void(int)> *job = job_;
    try {
      (*job)(id);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mu_);
      if (!error_) error_ = std::current_exception();
    }
    if (pending_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
      // The lock orders this notify after a waiter's check of pending_ (no lost wake-up).
      std::lock_guard<std::mutex> lock(mu_);
      done_.notify_one();
    }
  }
}

void ThreadPool::run(const std::function<void(int)> &fn) {
  if (workers_.empty()) {
    fn(0);
    return;
  }
  job_ = &fn;
  resting_.store(false, std::memory_order_relaxed);
  pending_.store(int(workers_.size()), std::memory_order_relaxed);
  {
    std::lock_guard<std::mutex> lock(mu_);
    error_ = nullptr;
    generation_.fetch_add(1, std::memory_order_release);
  }
  wake_.notify_all();
  std::exception_ptr mine;
  try {
    fn(size() - 1);
  } catch (...) {
    mine = std::current_exception();
  }
  auto finished = [&] { return pending_.load(std::memory_order_acquire) == 0; };
  if (!spin_until(finished)) {
    std::unique_lock<std::mutex> lock(mu_);
    done_.wait(lock, finished);
  }
  if (mine) std::rethrow_exception(mine);
  std::exception_ptr err;
  {
    std::lock_guard<std::mutex> lock(mu_);
    err = error_;
  }
  if (err) std::rethrow_exception(err);
}

}  // namespace sba
