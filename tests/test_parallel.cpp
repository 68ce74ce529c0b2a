// SPDX-License-Identifier: BSD-3-Clause
// The run-time support of the kernels and solvers (linked from the library's objects): where
// the thread pool's workers run (src/parallel.cpp), the work arrays whose pages are mapped up
// front (src/memory.cpp), and how a failed AMD or CHOLMOD call is reported
// (src/suitesparse_status.h; the solvers' matrices are valid by construction, so a status
// other than out of memory cannot be provoked through the API).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#if defined(__linux__)
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <sys/mman.h>
#include <unistd.h>
#endif

#include "memory.h"
#include "parallel.h"
#include "pool_parts.h"
#include "suitesparse_status.h"

#if defined(__linux__)
#include <sys/syscall.h>

namespace {
// Calls to sched_setaffinity that the tests did not make themselves: the library's.
std::atomic<long> library_mask_changes{0};
thread_local bool test_sets_mask = false;
}  // namespace

// Stands in for the C library's sched_setaffinity in this program (the library's objects
// are linked into it), so that every change of a thread's mask is seen, however briefly it
// lasts; the system call itself is made as the C library would.
extern "C" int sched_setaffinity(pid_t pid, size_t size, const cpu_set_t *mask) noexcept {
  if (!test_sets_mask) library_mask_changes.fetch_add(1);
  return int(syscall(SYS_sched_setaffinity, pid, size, mask));
}
#endif

namespace {

#if defined(__linux__)

// sched_setaffinity for the calling thread, made by the test (not counted as the library's).
int set_mask(const cpu_set_t &mask) {
  test_sets_mask = true;
  const int r = sched_setaffinity(0, sizeof mask, &mask);
  test_sets_mask = false;
  return r;
}

// Holds the calling thread on one CPU for a test's duration.
class PinCaller {
 public:
  explicit PinCaller(int cpu) {
    ok_ = sched_getaffinity(0, sizeof saved_, &saved_) == 0;
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(cpu, &one);
    ok_ = ok_ && set_mask(one) == 0;
  }
  ~PinCaller() { set_mask(saved_); }
  bool ok() const { return ok_; }

 private:
  cpu_set_t saved_;
  bool ok_ = false;
};

int allowed_cpus() {
  cpu_set_t mask;
  return sched_getaffinity(0, sizeof mask, &mask) == 0 ? CPU_COUNT(&mask) : 0;
}

// The scene of the tests below: the caller pinned to its CPU, and the pool's worker (slot 0)
// put next to it by hand at each round (on a virtual machine the scheduler does so when the
// worker is woken), then left free to move. After each round the worker's CPU and mask at
// its next job are recorded; returns false if the worker could not be put there.
struct Round {
  int worker_cpu = -1;
  cpu_set_t worker_mask;
};

bool worker_next_to_caller(sba::ThreadPool &pool, int here, const cpu_set_t &all, Round *r) {
  std::atomic<int> placed{-1};
  on_worker(pool, [&] {
    cpu_set_t to;
    CPU_ZERO(&to);
    CPU_SET(here, &to);
    if (set_mask(to) == 0) placed = sched_getcpu();
    set_mask(all);
  });
  if (placed.load() != here) return false;
  CPU_ZERO(&r->worker_mask);
  on_worker(pool, [&] {
    r->worker_cpu = sched_getcpu();
    sched_getaffinity(0, sizeof r->worker_mask, &r->worker_mask);
  });
  return true;
}

// With avoid_shared_cores, a worker on the caller's core leaves it at its next job, by a
// change of its own mask, and keeps the whole mask it had.
TEST(ThreadPool, AWorkerOnTheCallersCoreMovesToAFreeOne) {
  if (allowed_cpus() < 2) GTEST_SKIP() << "needs two CPUs";
  sba::ThreadPool pool(2, true);  // made before the pin: the worker may use every CPU
  ASSERT_EQ(pool.size(), 2);
  cpu_set_t all;
  ASSERT_EQ(sched_getaffinity(0, sizeof all, &all), 0);
  const int here = sched_getcpu();
  PinCaller pin(here);
  ASSERT_TRUE(pin.ok());
  const long before = library_mask_changes.load();
  for (int round = 0; round < 5; ++round) {
    Round r;
    ASSERT_TRUE(worker_next_to_caller(pool, here, all, &r));
    EXPECT_NE(r.worker_cpu, here) << "round " << round;
    EXPECT_TRUE(CPU_EQUAL(&r.worker_mask, &all)) << "round " << round;
  }
  EXPECT_GT(library_mask_changes.load() - before, 0);
}

// Without it (the default), the library changes no thread's mask at all, not even for a
// moment, whatever core its workers find themselves on.
TEST(ThreadPool, ByDefaultNoThreadsMaskIsEverChanged) {
  cpu_set_t all;
  ASSERT_EQ(sched_getaffinity(0, sizeof all, &all), 0);
  const int here = sched_getcpu();
  const long before = library_mask_changes.load();
  {
    sba::ThreadPool pool(2);
    ASSERT_EQ(pool.size(), 2);
    PinCaller pin(here);
    ASSERT_TRUE(pin.ok());
    for (int round = 0; round < 20; ++round) {
      Round r;
      ASSERT_TRUE(worker_next_to_caller(pool, here, all, &r));
      EXPECT_TRUE(CPU_EQUAL(&r.worker_mask, &all)) << "round " << round;
    }
  }
  {
    // Workers made while the caller is pinned: more threads than allowed cores.
    PinCaller pin(here);
    ASSERT_TRUE(pin.ok());
    sba::ThreadPool pool(3);
    for (int job = 0; job < 200; ++job) pool.run([](int) {});
  }
  EXPECT_EQ(library_mask_changes.load() - before, 0);
}

// Workers that inherit a one-CPU mask from their creator stay on that CPU (the mask is the
// caller's choice) and still run every job, avoid_shared_cores or not.
TEST(ThreadPool, WorkersKeepTheCallersMaskWhenThereIsNoFreeCore) {
  const int here = sched_getcpu();
  PinCaller pin(here);
  ASSERT_TRUE(pin.ok());
  sba::ThreadPool pool(3, true);
  std::vector<int> cpu(3, -1), count(3, 0);
  std::vector<cpu_set_t> mask(3);
  for (int job = 0; job < 200; ++job)
    pool.run([&](int t) {
      cpu[size_t(t)] = sched_getcpu();
      sched_getaffinity(0, sizeof mask[size_t(t)], &mask[size_t(t)]);
      ++count[size_t(t)];
    });
  for (int t = 0; t < pool.size(); ++t) {
    EXPECT_EQ(count[size_t(t)], 200) << "thread " << t;
    EXPECT_EQ(cpu[size_t(t)], here) << "thread " << t;
    EXPECT_EQ(CPU_COUNT(&mask[size_t(t)]), 1) << "thread " << t;
    EXPECT_TRUE(CPU_ISSET(here, &mask[size_t(t)])) << "thread " << t;
  }
}

// prefault maps every whole page of the range for writing, without writing to it; the
// partial pages at its ends are left alone.
// all_ranges and all_members: true only when every range (member) succeeds, every range
// runs, and the result does not depend on the thread count.
TEST(ThreadPool, AllRangesAndAllMembersAndTheirResults) {
  for (int threads : {1, 2, 3}) {
    SCOPED_TRACE(threads);
    sba::ThreadPool pool(threads);
    std::vector<std::atomic<int>> seen(100);
    EXPECT_TRUE(pool.all_ranges(100, [&](int, std::int64_t b, std::int64_t e) {
      for (std::int64_t k = b; k < e; ++k) seen[size_t(k)]++;
      return true;
    }));
    for (const auto &c : seen) EXPECT_EQ(c.load(), 1);
    EXPECT_FALSE(pool.all_ranges(100, [](int, std::int64_t b, std::int64_t e) { return !(b <= 57 && 57 < e); }));
    EXPECT_TRUE(pool.all_ranges(0, [](int, std::int64_t, std::int64_t) { return false; }));
    std::atomic<int> calls{0};
    EXPECT_FALSE(pool.all_members([&](int t) {
      ++calls;
      return t != pool.size() - 1;
    }) && pool.size() > 1);
    EXPECT_EQ(calls.load(), pool.size());
    calls = 0;
    EXPECT_TRUE(pool.all_members([&](int t) {
      ++calls;
      return t == 0;
    }, true));
    EXPECT_EQ(calls.load(), 1);
  }
}

// deterministic_sum's definition: blocks of 4096 terms, each summed in ascending order, then
// the blocks' sums in block order. Terms of mixed magnitudes make every other order round
// differently. Lengths around whole blocks and numbers of blocks that each thread's share
// splits into eights, fours, twos and ones.
TEST(ThreadPool, DeterministicSumIsItsBlocksInOrder) {
  std::vector<double> v(size_t(4096) * 23 + 3);
  std::uint64_t x = 12345;
  for (double &t : v) {
    x = x * 6364136223846793005ULL + 1442695040888963407ULL;
    t = double(x >> 11) * 0x1p-53 * ((x >> 7) % 3 == 0 ? 1e8 : 1.0) - 0.3;
  }
  const auto reference = [&](std::int64_t n) {
    double total = 0.0;
    for (std::int64_t b = 0; b < n; b += 4096) {
      double s = 0.0;
      for (std::int64_t k = b; k < std::min<std::int64_t>(n, b + 4096); ++k) s += v[size_t(k)] * v[size_t(k)];
      total += s;
    }
    return total;
  };
  for (int threads : {1, 2, 3}) {
    sba::ThreadPool pool(threads);
    for (std::int64_t n : {std::int64_t(0), std::int64_t(1), std::int64_t(4095), std::int64_t(4096),
                           std::int64_t(4097), std::int64_t(4096) * 3, std::int64_t(4096) * 8 + 5,
                           std::int64_t(4096) * 15, std::int64_t(4096) * 23 + 3}) {
      SCOPED_TRACE(testing::Message() << threads << " threads, n " << n);
      const double got = sba::deterministic_sum(pool, n, [&](std::int64_t k) { return v[size_t(k)] * v[size_t(k)]; });
      const double want = reference(n);
      EXPECT_EQ(std::memcmp(&got, &want, sizeof got), 0) << got << " against " << want;
    }
  }
}

// Work handed to the pool while, and after, a foreign library's threads had the cores.
TEST(ThreadPool, RunsWithinAndAfterForeignThreads) {
  sba::ThreadPool pool(2);
  std::atomic<int> n{0};
  {
    const sba::ThreadPool::ForeignThreads guard(pool);
    pool.run([&](int) { ++n; });
  }
  pool.run([&](int) { ++n; });
  EXPECT_EQ(n.load(), 2 * pool.size());
}

// Every part of every job runs once, whether its worker or the caller (done with its own
// part first) runs it: jobs whose caller's part is empty, so that the two race for the
// workers' parts.
TEST(ThreadPool, EveryPartRunsOnceWhoeverRunsIt) {
  sba::ThreadPool pool(3);
  ASSERT_EQ(pool.size(), 3);
  const int jobs = 20000;
  std::vector<int> count(3, 0);
  for (int job = 0; job < jobs; ++job)
    pool.run([&](int t) {
      if (t < 2) ++count[size_t(t)];
    });
  EXPECT_EQ(count[0], jobs);
  EXPECT_EQ(count[1], jobs);
}

#if defined(__linux__)
// A worker held in a signal handler until released: a thread the scheduler does not run.
std::atomic<bool> hold_worker{false}, worker_held{false};
void held_here(int) {
  worker_held = true;
  while (hold_worker.load()) {
  }
}

// A worker that cannot run (descheduled on a machine busier than its cores; here held in a
// signal handler) does not hold the job up: the caller, done with its part, does the
// worker's. Waiting for the worker instead would return only once a watchdog releases it.
TEST(ThreadPool, TheCallerDoesThePartOfAWorkerThatCannotRun) {
  sba::ThreadPool pool(2);
  ASSERT_EQ(pool.size(), 2);
  pthread_t worker{};
  on_worker(pool, [&] { worker = pthread_self(); });
  struct sigaction held {}, old {};
  held.sa_handler = held_here;
  sigemptyset(&held.sa_mask);
  ASSERT_EQ(sigaction(SIGUSR1, &held, &old), 0);
  hold_worker = true;
  worker_held = false;
  ASSERT_EQ(pthread_kill(worker, SIGUSR1), 0);
  for (int k = 0; k < 5000 && !worker_held.load(); ++k) usleep(1000);
  if (!worker_held.load()) {
    hold_worker = false;
    sigaction(SIGUSR1, &old, nullptr);
    GTEST_SKIP() << "the signal did not reach the worker";
  }
  std::atomic<bool> returned{false};
  std::thread watchdog([&] {
    for (int k = 0; k < 3000 && !returned.load(); ++k) usleep(1000);
    hold_worker = false;
  });
  pthread_t ran{};
  pool.run([&](int t) {
    if (t == 0) ran = pthread_self();
  });
  returned = true;
  const bool released_by_watchdog = !hold_worker.load();
  hold_worker = false;
  watchdog.join();
  sigaction(SIGUSR1, &old, nullptr);
  EXPECT_FALSE(released_by_watchdog);
  EXPECT_TRUE(pthread_equal(ran, pthread_self()));
  // The worker, back, takes its own parts again.
  on_worker(pool, [&] { ran = pthread_self(); });
  EXPECT_TRUE(pthread_equal(ran, worker));
}
#endif

// The message a failure carries (empty for one that is not a std::runtime_error).
template <class Throw>
std::string internal_error(Throw fn) {
  try {
    fn();
  } catch (const std::runtime_error &e) {
    return e.what();
  } catch (...) {
  }
  return "";
}

// A forced unwind (pthread_exit here; glibc's thread cancellation and Python ending a daemon
// thread work the same way) in a job of the pool. Each case runs in a child process (a death
// test), since swallowing the unwind aborts the process and a lost wake-up hangs it.
#if defined(__linux__)
struct CallerEnded {
  std::atomic<int> workers_done{0};
  int done_when_unwound = -1;
  bool returned = false;
};

// Records, as the unwind passes it, how many workers had finished their part of the job.
struct UnwindProbe {
  CallerEnded &st;
  ~UnwindProbe() { st.done_when_unwound = st.workers_done.load(); }
};

void *end_the_caller_in_a_job(void *arg) {
  CallerEnded &st = *static_cast<CallerEnded *>(arg);
  sba::ThreadPool pool(3);
  const UnwindProbe probe{st};
  pool.run([&](int t) {
    if (t == pool.size() - 1) pthread_exit(nullptr);
    usleep(30000);
    st.workers_done.fetch_add(1);
  });
  st.returned = true;
  return nullptr;
}

// The calling thread ends inside its own part of a job: the unwind waits for the workers,
// who still use the job's captures, then goes on (freeing the pool) and ends the thread.
int caller_ended_case() {
  CallerEnded st;
  pthread_t t;
  if (pthread_create(&t, nullptr, end_the_caller_in_a_job, &st) != 0) return 3;
  pthread_join(t, nullptr);
  std::fprintf(stderr, "returned=%d done_when_unwound=%d\n", int(st.returned), st.done_when_unwound);
  return !st.returned && st.done_when_unwound == 2 ? 0 : 1;
}

TEST(ThreadPoolDeathTest, ForcedUnwindOfTheCallerWaitsForTheWorkersAndEndsOnlyIt) {
  EXPECT_EXIT(std::_Exit(caller_ended_case()), testing::ExitedWithCode(0), "returned=0 done_when_unwound=2");
}

// A worker ends inside a job: it is let go, the job fails in the caller (it is incomplete)
// and so does every later job, instead of waiting for the lost member forever.
int worker_ended_case() {
  std::string first, second;
  {
    sba::ThreadPool pool(3);
    first = internal_error([&] { on_worker(pool, [] { pthread_exit(nullptr); }); });
    second = internal_error([&] { pool.run([](int) {}); });
  }
  std::fprintf(stderr, "first: %s\nsecond: %s\n", first.c_str(), second.c_str());
  const std::string lost = "a worker thread of the solve was ended (pthread_exit or pthread_cancel in a callback)";
  return first == lost && second == lost ? 0 : 1;
}

TEST(ThreadPoolDeathTest, ForcedUnwindOfAWorkerFailsThisAndLaterJobs) {
  EXPECT_EXIT(std::_Exit(worker_ended_case()), testing::ExitedWithCode(0),
              "first: a worker thread of the solve was ended");
}
#endif

TEST(Memory, PrefaultMapsTheWholePagesOfTheRange) {
  const long page = sysconf(_SC_PAGESIZE);
  ASSERT_GT(page, 0);
  const size_t npages = 16, bytes = npages * size_t(page);
  void *raw = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  ASSERT_NE(raw, MAP_FAILED);
  auto *base = static_cast<unsigned char *>(raw);
  std::vector<unsigned char> resident(npages);
  ASSERT_EQ(mincore(raw, bytes, resident.data()), 0);
  for (size_t k = 0; k < npages; ++k) ASSERT_EQ(resident[k] & 1, 0) << "page " << k << " before";
  if (madvise(base + (npages - 1) * size_t(page), size_t(page), MADV_POPULATE_WRITE) != 0) {
    munmap(raw, bytes);
    GTEST_SKIP() << "this kernel has no MADV_POPULATE_WRITE (Linux 5.14 and later)";
  }
  // From the middle of page 0 to the middle of page 14: pages 1 to 13 are whole.
  sba::prefault(base + page / 2, size_t(page) * 14);
  ASSERT_EQ(mincore(raw, bytes, resident.data()), 0);
  for (size_t k = 0; k + 1 < npages; ++k)
    EXPECT_EQ(resident[k] & 1, k >= 1 && k <= 13 ? 1 : 0) << "page " << k;
  for (size_t q = 0; q < bytes; ++q) ASSERT_EQ(base[q], 0) << "byte " << q;
  munmap(raw, bytes);
}

#endif  // __linux__

// resize_prefaulted is resize: n zeros, for sizes below and above the prefault threshold,
// and for a vector that already has the capacity.
TEST(Memory, ResizePrefaultedGivesZeros) {
  for (size_t n : {size_t(0), size_t(1), size_t(1000), size_t(8191), size_t(8192), size_t(1) << 20}) {
    std::vector<double> v;
    sba::resize_prefaulted(v, n);
    ASSERT_EQ(v.size(), n);
    for (size_t k = 0; k < n; ++k) ASSERT_EQ(v[k], 0.0) << "n " << n << ", entry " << k;
  }
  std::vector<double> w;
  w.reserve(100000);
  sba::resize_prefaulted(w, 100000);
  ASSERT_EQ(w.size(), 100000u);
  for (double x : w) ASSERT_EQ(x, 0.0);
}

// Out of memory stays a resource failure; every other failure status is an internal error
// that names the routine and the status, never "out of memory".
TEST(SuiteSparseStatus, OnlyOutOfMemoryIsBadAlloc) {
  EXPECT_THROW(sba::throw_amd_failure("amd_l_order", AMD_OUT_OF_MEMORY), std::bad_alloc);
  EXPECT_THROW(sba::throw_cholmod_failure("cholmod_analyze", CHOLMOD_OUT_OF_MEMORY), std::bad_alloc);
  EXPECT_EQ(internal_error([] { sba::throw_amd_failure("amd_l_order", AMD_INVALID); }),
            "AMD amd_l_order failed with status -2 (invalid input)");
  EXPECT_EQ(internal_error([] { sba::throw_amd_failure("amd_l_order", AMD_OK_BUT_JUMBLED); }),
            "AMD amd_l_order failed with status 1 (ok but jumbled)");
  EXPECT_EQ(internal_error([] { sba::throw_cholmod_failure("cholmod_factorize", CHOLMOD_INVALID); }),
            "CHOLMOD cholmod_factorize failed with status -4 (invalid input)");
  EXPECT_EQ(internal_error([] { sba::throw_cholmod_failure("cholmod_analyze", CHOLMOD_TOO_LARGE); }),
            "CHOLMOD cholmod_analyze failed with status -3 (integer overflow)");
  EXPECT_EQ(internal_error([] { sba::throw_cholmod_failure("cholmod_solve", 77); }),
            "CHOLMOD cholmod_solve failed with status 77 (unknown status)");
}

}  // namespace
