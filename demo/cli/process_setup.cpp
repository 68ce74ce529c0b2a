// SPDX-License-Identifier: BSD-3-Clause
// The process of each program set up for the limits a user may put on it, before anything else
// runs: linked into each program and sba_bench (the object library sbaprocess,
// demo/CMakeLists.txt), not into sbacli, whose other users (the tests, the micro-benchmarks)
// choose their own process settings.
//
// - A file-size limit (ulimit -f): a write past it fails with EFBIG, which the writers report and
//   clean up after as they do a full disk, instead of SIGXFSZ killing the program midway
//   through a file and leaving its temporary behind.
// - An address-space limit (ulimit -v): OpenBLAS starts a worker thread per core as it loads,
//   and each worker reserves a buffer far larger than a thread's stack. Under the limit the
//   start of a worker can fail (OpenBLAS then raises SIGINT, as if the user had interrupted the
//   program), or its reservation can, and the worker retries it for ever, while OpenBLAS waits
//   for its workers when the program exits, which then never ends. OpenBLAS reads its thread
//   count from the environment once, in its constructor, so the program starts again, once,
//   with OPENBLAS_NUM_THREADS=1 before any library's constructor has run, unless the user chose
//   a count (OPENBLAS_NUM_THREADS, GOTO_NUM_THREADS or OMP_NUM_THREADS). The library's own
//   threads (--threads) are not OpenBLAS's and stay as asked.
//
// Both happen in a function of the executable's .preinit_array, which the dynamic loader runs
// before the constructors of the shared libraries; it calls only system calls' wrappers, and
// builds the new environment on its stack, since nothing else is set up yet.
#include <alloca.h>
#include <sys/resource.h>
#include <unistd.h>

#include <csignal>
#include <cstring>
#include <initializer_list>

namespace {

bool has_variable(char **envp, const char *name) {
  const std::size_t len = std::strlen(name);
  for (char **e = envp; *e; ++e)
    if (std::strncmp(*e, name, len) == 0 && (*e)[len] == '=') return true;
  return false;
}

void set_up_process(int, char **argv, char **envp) {
  std::signal(SIGXFSZ, SIG_IGN);
  rlimit lim{};
  if (!envp || getrlimit(RLIMIT_AS, &lim) != 0 || lim.rlim_cur == RLIM_INFINITY) return;
  for (const char *chosen : {"OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS"})
    if (has_variable(envp, chosen)) return;
  std::size_t n = 0;
  while (envp[n]) ++n;
  char **env = static_cast<char **>(alloca((n + 2) * sizeof(char *)));
  std::memcpy(env, envp, n * sizeof(char *));
  static char one_thread[] = "OPENBLAS_NUM_THREADS=1";
  env[n] = one_thread;
  env[n + 1] = nullptr;
  execve("/proc/self/exe", argv, env);
  // Not started again (no /proc, say): the program goes on as it is.
}

__attribute__((section(".preinit_array"), used)) void (*const kSetUpProcess)(int, char **, char **) = set_up_process;

}  // namespace
