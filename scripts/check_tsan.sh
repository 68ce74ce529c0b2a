#!/bin/sh
# SPDX-License-Identifier: BSD-3-Clause
# make check-tsan: runs the concurrency tests of the ThreadSanitizer build (configured by the
# Makefile in BUILD_DIR) and fails on any test failure or any ThreadSanitizer report.
#   Drivers.FourConcurrentSolvesMatchASequentialOne      four solves at once in one process
#   Solvers/EverySolver.ResultsDoNotDependOnTheThreadCount  the library's own thread pool
#                                                        (src/parallel.*) with 2, 3, 5 threads,
#                                                        every linear solver
#   ParallelCallbacks.*                                  the caller's callbacks on those threads
#   CameraParams.TheSameBitsForAnyThreadCount            held and shared camera parameters (the
#                                                        bordered solve) on 1 and 2 threads
#   DenseThreads.ConcurrentCallsMatchSequential          the LAPACK helpers from many threads
#   DenseCholesky.*                                      the dense Cholesky of S, whose phases
#                                                        meet at spin barriers, on 2, 3, 5 threads
#   ThreadPool.*                                         the pool's workers leaving the caller's
#                                                        core (the CPU slots they share), and
#                                                        the caller taking over the part of a
#                                                        worker that has not begun it
#   ThreadPoolDeathTest.*                                a thread of the pool ended inside a job
#                                                        (forced unwind), each in a child process
# No suppressions are used. LAPACK/BLAS, SuiteSparse and libgomp are not instrumented: TSan
# does not see their memory accesses, only their calls to intercepted functions (malloc,
# memset, mmap ...). OpenBLAS (the pthread build, when the library was configured with it)
# hands buffers to its own worker threads through spin-waits on plain memory that TSan cannot
# see, and TSan then reports OpenBLAS's internal memset of such a buffer (dscal_k, called
# from dgeqrf) as a race with the mmap that created it. CHOLMOD's OpenMP regions do the same
# through libgomp, whose barriers (futexes) TSan does not see either: a worker's memset of a
# block that the calling thread allocated with cholmod_l_malloc is reported. Both are reports
# about those libraries' own threads, not ours. OPENBLAS_NUM_THREADS=1 keeps OpenBLAS inside
# the calling thread; CHOLMOD asks libgomp for its threads explicitly, so OMP_NUM_THREADS=1
# is not enough and OMP_THREAD_LIMIT=1 is what keeps it there. Every thread TSan then sees is
# one of the library's (src/parallel.*) or the tests'.
#
# usage: scripts/check_tsan.sh BUILD_DIR
set -eu

build=$(cd "$1" && pwd)
logs=$build/sanitizer-logs
rm -rf "$logs"
mkdir -p "$logs"
export OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 OMP_THREAD_LIMIT=1
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:history_size=4:log_path=$logs/tsan"

status=0
run() {
  echo "check-tsan: $1 --gtest_filter=$2"
  "$build/tests/$1" --gtest_filter="$2" --gtest_brief=1 || status=1
}
run test_drivers 'Drivers.FourConcurrentSolvesMatchASequentialOne'
run test_solvers 'Solvers/EverySolver.ResultsDoNotDependOnTheThreadCount/*'
run test_solvers 'ParallelCallbacks.*'
run test_camera_params 'CameraParams.TheSameBitsForAnyThreadCount'
run test_dense 'DenseThreads.ConcurrentCallsMatchSequential'
run test_kernels 'DenseCholesky.*'
run test_parallel 'ThreadPool.*:ThreadPoolDeathTest.*'

reports=$(find "$logs" -type f | sort)
if [ -n "$reports" ]; then
  echo "check-tsan: ThreadSanitizer reports:"
  for r in $reports; do
    echo "---- $r"
    cat "$r"
  done
  status=1
fi
if [ "$status" -eq 0 ]; then
  echo "check-tsan: no test failure, no ThreadSanitizer report"
fi
exit $status
