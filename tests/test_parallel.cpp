// The run-time support of the kernels (linked from the library's objects): where the thread
// pool's workers run (src/parallel.cpp), and the work arrays whose pages are mapped up front
// (src/memory.cpp).
#include <gtest/gtest.h>

#include <atomic>
#include <vector>

#if defined(__linux__)
#include <sched.h>
#include <sys/mman.h>
#include <unistd.h>
#endif

#include "memory.h"
#include "parallel.h"

namespace {

#if defined(__linux__)

// Holds the calling thread on one CPU for a test's duration.
class PinCaller {
 public:
  explicit PinCaller(int cpu) {
    ok_ = sched_getaffinity(0, sizeof saved_, &saved_) == 0;
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(cpu, &one);
    ok_ = ok_ && sched_setaffinity(0, sizeof one, &one) == 0;
  }
  ~PinCaller() { sched_setaffinity(0, sizeof saved_, &saved_); }
  bool ok() const { return ok_; }

 private:
  cpu_set_t saved_;
  bool ok_ = false;
};

int allowed_cpus() {
  cpu_set_t mask;
  return sched_getaffinity(0, sizeof mask, &mask) == 0 ? CPU_COUNT(&mask) : 0;
}

// A worker put on the caller's core (here by hand; on a virtual machine by the scheduler,
// when the worker is woken) leaves it at its next job, and keeps the whole mask it had.
TEST(ThreadPool, AWorkerOnTheCallersCoreMovesToAFreeOne) {
  if (allowed_cpus() < 2) GTEST_SKIP() << "needs two CPUs";
  sba::ThreadPool pool(2);  // made before the pin: the worker may use every CPU
  ASSERT_EQ(pool.size(), 2);
  cpu_set_t all;
  ASSERT_EQ(sched_getaffinity(0, sizeof all, &all), 0);
  const int here = sched_getcpu();
  PinCaller pin(here);
  ASSERT_TRUE(pin.ok());
  for (int round = 0; round < 5; ++round) {
    std::atomic<int> worker_cpu{-1};
    // The worker (slot 0) moves itself next to the caller, then lifts its own pin.
    pool.run([&](int t) {
      if (t != 0) return;
      cpu_set_t to;
      CPU_ZERO(&to);
      CPU_SET(here, &to);
      if (sched_setaffinity(0, sizeof to, &to) == 0) worker_cpu = sched_getcpu();
      sched_setaffinity(0, sizeof all, &all);
    });
    ASSERT_EQ(worker_cpu.load(), here);
    cpu_set_t worker_mask;
    CPU_ZERO(&worker_mask);
    pool.run([&](int t) {
      if (t != 0) return;
      worker_cpu = sched_getcpu();
      sched_getaffinity(0, sizeof worker_mask, &worker_mask);
    });
    EXPECT_NE(worker_cpu.load(), here) << "round " << round;
    EXPECT_TRUE(CPU_EQUAL(&worker_mask, &all)) << "round " << round;
  }
}

// Workers that inherit a one-CPU mask from their creator stay on that CPU (the mask is the
// caller's choice) and still run every job.
TEST(ThreadPool, WorkersKeepTheCallersMaskWhenThereIsNoFreeCore) {
  const int here = sched_getcpu();
  PinCaller pin(here);
  ASSERT_TRUE(pin.ok());
  sba::ThreadPool pool(3);
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

}  // namespace
