// SPDX-License-Identifier: BSD-3-Clause
// sba_bench's process side: the memory and CPU accounting of a run (from /proc/self and
// getrusage), the BLAS's threads, and the child process each run is measured in.
#include <dirent.h>
#include <dlfcn.h>
#include <fcntl.h>
#include <malloc.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <sys/time.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <new>
#include <string>
#include <thread>
#include <vector>

#include "bench_run.h"

namespace sbabench {

int hardware_threads() { return std::max(1, static_cast<int>(std::thread::hardware_concurrency())); }

double core_round_trip_ns() {
  cpu_set_t mask;
  CPU_ZERO(&mask);
  if (sched_getaffinity(0, sizeof mask, &mask) != 0) return NAN;
  int cpus[2] = {-1, -1}, found = 0;
  for (int c = 0; c < CPU_SETSIZE && found < 2; ++c)
    if (CPU_ISSET(c, &mask)) cpus[found++] = c;
  if (found < 2) return NAN;
  constexpr int kWarm = 200, kTrips = 2000;
  struct alignas(64) Line {
    std::atomic<int> turn{0};
  } line;
  std::atomic<int> pinned{0};
  const auto pin = [&pinned](int cpu) {
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(cpu, &one);
    if (pthread_setaffinity_np(pthread_self(), sizeof one, &one) == 0) pinned.fetch_add(1);
  };
  // Turn 2k+1 is the timer's write, 2k+2 the echo's.
  const auto await = [&line](int turn) {
    while (line.turn.load(std::memory_order_acquire) != turn) {
#if defined(__x86_64__) || defined(__i386__)
      __builtin_ia32_pause();
#endif
    }
  };
  double ns = NAN;
  std::thread echo([&] {
    pin(cpus[1]);
    for (int k = 0; k < kWarm + kTrips; ++k) {
      await(2 * k + 1);
      line.turn.store(2 * k + 2, std::memory_order_release);
    }
  });
  std::thread timer([&] {
    pin(cpus[0]);
    std::chrono::steady_clock::time_point start;
    for (int k = 0; k < kWarm + kTrips; ++k) {
      if (k == kWarm) start = std::chrono::steady_clock::now();
      line.turn.store(2 * k + 1, std::memory_order_release);
      await(2 * k + 2);
    }
    ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start).count() / kTrips;
  });
  timer.join();
  echo.join();
  return pinned.load() == 2 ? ns : NAN;
}

long long status_kb(const char *field) {
  std::FILE *f = std::fopen("/proc/self/status", "r");
  if (!f) return -1;
  char line[256];
  long long kb = -1;
  const std::size_t len = std::strlen(field);
  while (std::fgets(line, sizeof line, f))
    if (std::strncmp(line, field, len) == 0 && line[len] == ':') {
      kb = std::atoll(line + len + 1);
      break;
    }
  std::fclose(f);
  return kb;
}

long long file_rss() {
  const long long f = status_kb("RssFile"), s = status_kb("RssShmem");
  return f < 0 || s < 0 ? -1 : (f + s) * 1024;
}

// User + system time of every thread of this process so far.
double process_cpu_seconds() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  const auto sec = [](const timeval &t) { return double(t.tv_sec) + 1e-6 * double(t.tv_usec); };
  return sec(ru.ru_utime) + sec(ru.ru_stime);
}

bool reset_peak_rss() {
  const int fd = ::open("/proc/self/clear_refs", O_WRONLY);
  if (fd < 0) return false;
  const bool ok = ::write(fd, "5", 1) == 1;
  ::close(fd);
  return ok;
}

void set_status(RunResult *r, const std::string &s) {
  std::snprintf(r->status, sizeof r->status, "%s", s.c_str());
}

BlasSetThreads blas_set_threads() {
  return reinterpret_cast<BlasSetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
}

namespace {

// Whether any thread of this process but the calling one is running (state R in
// /proc/self/task/TID/stat).
bool other_threads_running() {
  const long self = syscall(SYS_gettid);
  DIR *dir = opendir("/proc/self/task");
  if (!dir) return false;
  bool running = false;
  while (const dirent *e = readdir(dir)) {
    const long tid = std::atol(e->d_name);
    if (tid <= 0 || tid == self) continue;
    char path[64], buf[512];
    std::snprintf(path, sizeof path, "/proc/self/task/%ld/stat", tid);
    std::FILE *f = std::fopen(path, "r");
    if (!f) continue;
    const std::size_t len = std::fread(buf, 1, sizeof buf - 1, f);
    std::fclose(f);
    buf[len] = '\0';
    const char *close = std::strrchr(buf, ')');  // the state follows the command's ")"
    if (close && close[1] == ' ' && close[2] == 'R') running = true;
  }
  closedir(dir);
  return running;
}

// openblas_set_num_threads starts OpenBLAS's worker threads in this (forked) child, and
// each of them spins for about 0.1 s of CPU time before it sleeps. A run started at once
// would share the cores with them, and a 1-thread run would use more than one core.
// Real programs meet those threads asleep unless they have just called the BLAS, so the
// run waits (at most a second) until they are.
void wait_for_idle_threads() {
  for (int k = 0; k < 500 && other_threads_running(); ++k)
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
}

// probe: measure the price of the cores' exchanges before and after the solve, the latter
// once the BLAS's threads are idle. Not in a run in the program's own process (--no-fork),
// which times the whole process: a program that has solved exits at once, without waiting
// for OpenBLAS's workers to stop spinning (up to a tenth of a second after their last call,
// or after the library loaded).
void execute(Problem &prob, const RunSpec &spec, int itmax, bool consume, bool probe, RunResult *r,
             Trace *trace) {
  if (spec.blas_threads > 0)
    if (BlasSetThreads set = blas_set_threads()) {
      set(spec.blas_threads);
      wait_for_idle_threads();
    }
  const double before = probe ? core_round_trip_ns() : NAN;
  try {
    if (spec.engine == Engine::Sba) run_sba(prob, spec, itmax, consume, r, trace);
    else run_ceres(prob, spec, itmax, consume, r, trace);
  } catch (const std::bad_alloc &) {
    r->ok = 0;
    set_status(r, "out of memory");
  } catch (const std::exception &e) {
    r->ok = 0;
    set_status(r, std::string("exception: ") + e.what());
  }
  r->ntrace = static_cast<int>(trace->size());
  r->core_rt_before = before;
  if (!probe) return;
  wait_for_idle_threads();  // a BLAS the solve called may still spin
  r->core_rt_after = core_round_trip_ns();
}

// Frees what the run does not use, so that the child's RSS is the run's: both sba (through
// its _vis entry point) and Ceres take the observation index, neither the dense vmask.
void release_unused(Problem &prob, Engine) {
  std::vector<char>().swap(prob.vmask);
  malloc_trim(0);
}

bool write_all(int fd, const void *data, std::size_t size) {
  const char *p = static_cast<const char *>(data);
  while (size > 0) {
    const ssize_t w = ::write(fd, p, size);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    p += w;
    size -= static_cast<std::size_t>(w);
  }
  return true;
}

// One iteration of the run, its memory handed back: the pages of code (and the threads) the
// measured solve will use are in place before its peak is reset.
void warm_up(Problem &prob, const RunSpec &spec, bool probe) {
  RunResult r;
  Trace trace;
  execute(prob, spec, 1, false, probe, &r, &trace);
  malloc_trim(0);
}

}  // namespace

Run run_forked(Problem &prob, const RunSpec &spec, int itmax, double timeout, bool warm) {
  Run run;
  run.spec = spec;
  int fds[2];
  if (::pipe(fds) != 0) {
    set_status(&run.r, std::string("pipe: ") + std::strerror(errno));
    return run;
  }
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    set_status(&run.r, std::string("fork: ") + std::strerror(errno));
    ::close(fds[0]);
    ::close(fds[1]);
    return run;
  }
  if (pid == 0) {
    ::close(fds[0]);
    release_unused(prob, spec.engine);
    if (warm) warm_up(prob, spec, true);
    RunResult r;
    Trace trace;
    execute(prob, spec, itmax, true, true, &r, &trace);
    const bool ok = write_all(fds[1], &r, sizeof r) &&
                    write_all(fds[1], trace.data(), trace.size() * sizeof(trace[0]));
    ::close(fds[1]);
    ::_exit(ok ? 0 : 3);
  }
  ::close(fds[1]);
  std::vector<char> bytes;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout);
  bool timed_out = false;
  for (;;) {
    const double left = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0) {
      timed_out = true;
      break;
    }
    pollfd pfd{fds[0], POLLIN, 0};
    const int pr = ::poll(&pfd, 1, static_cast<int>(std::min(left * 1000.0 + 1, 60000.0)));
    if (pr < 0 && errno == EINTR) continue;
    if (pr <= 0) continue;
    char buf[65536];
    const ssize_t got = ::read(fds[0], buf, sizeof buf);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) break;
    bytes.insert(bytes.end(), buf, buf + got);
  }
  ::close(fds[0]);
  if (timed_out) ::kill(pid, SIGKILL);
  int wstatus = 0;
  rusage ru{};
  while (::wait4(pid, &wstatus, 0, &ru) < 0 && errno == EINTR) {
  }
  run.child_maxrss = static_cast<long long>(ru.ru_maxrss) * 1024;
  if (timed_out) {
    set_status(&run.r, "timeout after " + std::to_string(static_cast<long>(timeout)) + " s");
    return run;
  }
  if (bytes.size() < sizeof(RunResult)) {
    std::string why = "child failed";
    if (WIFSIGNALED(wstatus)) why += std::string(": signal ") + strsignal(WTERMSIG(wstatus));
    else if (WIFEXITED(wstatus)) why += ": exit " + std::to_string(WEXITSTATUS(wstatus));
    set_status(&run.r, why);
    return run;
  }
  std::memcpy(&run.r, bytes.data(), sizeof(RunResult));
  const std::size_t ntrace = (bytes.size() - sizeof(RunResult)) / sizeof(run.trace[0]);
  run.trace.resize(ntrace);
  if (ntrace > 0) std::memcpy(run.trace.data(), bytes.data() + sizeof(RunResult), ntrace * sizeof(run.trace[0]));
  return run;
}

Run run_inline(Problem &prob, const RunSpec &spec, int itmax, bool warm) {
  Run run;
  run.spec = spec;
  if (warm) warm_up(prob, spec, false);
  execute(prob, spec, itmax, false, false, &run.r, &run.trace);
  return run;
}

}  // namespace sbabench
