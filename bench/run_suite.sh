#!/bin/sh
# SPDX-License-Identifier: BSD-3-Clause
# Builds the benchmarks (Release) and runs the whole suite, writing bench/results/:
# results.md (tables), results.json (one JSON object per run), scaling.png (gnuplot),
# kernels.json and block_kernels.json (Google Benchmark), features.md (robust-loss overhead and
# covariance time against problem size), and the orbit and photo series (bench/series.sh:
# NAME_series.md, .json and .png). With --quick or --report-only, only run_suite.py's part.
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
cmake --build "$build" -j"${SBA_BUILD_JOBS:-2}" --target sba_bench kernels_benchmark \
  block_kernels_benchmark features_bench
# Google Benchmark records the path of the executable it ran: the results keep its name only,
# not the directories of the machine that produced them.
drop_paths() {
  for f in "$@"; do
    if [ -f "$f" ]; then sed -i 's|"executable": "[^"]*/\([^"/]*\)"|"executable": "\1"|' "$f"; fi
  done
}
python3 "$here/run_suite.py" --build "$build" "$@"
drop_paths "$here/results/kernels.json"
case " $* " in
  *" --report-only "*|*" --quick "*) exit 0 ;;
esac
"$build/bench/block_kernels_benchmark" --benchmark_min_time=0.5 \
  --benchmark_out="$here/results/block_kernels.json" --benchmark_out_format=json
drop_paths "$here/results/block_kernels.json"
rm -f "$here/results/features.json"
{
  echo "# sba_ext.h features: robust-loss overhead and covariance time"
  echo
  echo "Generated $(date -u '+%Y-%m-%d %H:%M UTC') by \`$build/bench/features_bench\`"
  echo "(sbagen orbit scenes, fixed K, tracks 2..8, every hardware thread, chol; time per"
  echo "linear system tried over 10 LM iterations, and the covariance of every camera and point"
  echo "at the least-squares solution with two cameras fixing the gauge)."
  echo
  "$build/bench/features_bench" --out "$here/results/features.json"
} > "$here/results/features.md"
"$here/series.sh" orbit "$build"
"$here/series.sh" photo "$build"
