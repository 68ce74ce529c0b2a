#!/bin/sh
# Builds the benchmarks (Release) and runs the whole suite, writing bench/results/:
# results.md (tables), results.json (one JSON object per run), scaling.png (gnuplot),
# kernels.json (Google Benchmark).
#
#   bench/run_suite.sh [BUILD_DIR] [run_suite.py options: --quick, --only GROUPS, --timeout SEC ...]
#
# BUILD_DIR defaults to build-bench/ in the source tree. Needs libceres-dev, libbenchmark-dev
# and, for the plot, gnuplot (Debian: gnuplot-nox). The shared data is looked up in
# ../shared/data (override with --data DIR).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
build="$root/build-bench"
case "${1:-}" in
  ""|-*) ;;
  *) build=$1; shift ;;
esac
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DSBA_BUILD_BENCH=ON >/dev/null
cmake --build "$build" -j"${SBA_BUILD_JOBS:-2}" --target sba_bench kernels_benchmark
exec python3 "$here/run_suite.py" --build "$build" "$@"
