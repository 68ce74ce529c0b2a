#!/bin/sh
# SPDX-License-Identifier: BSD-3-Clause
# make check-kernels: the numeric tests (ctest label "numeric": the 1.6 comparisons, eucsbademo,
# the BAL and COLMAP goldens, the Octave and Python suites) run again under other floating-point
# kernels, so that a figure a test asserts is one of the problem and not of this machine's
# rounding. A user's CPU picks other kernels: OpenBLAS chooses its own by the CPU at load time
# (OPENBLAS_CORETYPE overrides it), and the library its AVX2 build or its portable one
# (SBA_KERNELS=portable forces the latter). Each run below is one that another x86-64 CPU would
# make, as far as this CPU can run it:
#   OPENBLAS_CORETYPE=Haswell                               AVX2 and FMA, no AVX-512
#   OPENBLAS_CORETYPE=SandyBridge SBA_KERNELS=portable       AVX without AVX2: both portable
#   OPENBLAS_CORETYPE=Prescott                              SSE3 only
# Usage: check_kernels.sh BUILD_DIR JOBS
set -u
build=$1
jobs=$2
flags=$(grep -m 1 '^flags' /proc/cpuinfo 2>/dev/null)
has() {
  case " $flags " in *" $1 "*) return 0 ;; esac
  return 1
}
runs=""
if has avx2 && has fma; then runs="$runs OPENBLAS_CORETYPE=Haswell"; fi
if has avx; then runs="$runs OPENBLAS_CORETYPE=SandyBridge,SBA_KERNELS=portable"; fi
runs="$runs OPENBLAS_CORETYPE=Prescott"
status=0
for run in $runs; do
  settings=$(echo "$run" | tr ',' ' ')
  echo "check-kernels: $settings"
  # shellcheck disable=SC2086  # the settings are words on purpose
  env $settings ctest --test-dir "$build" -L numeric --output-on-failure --no-tests=error -j "$jobs" || status=1
done
exit $status
