#!/bin/sh
# SPDX-License-Identifier: BSD-3-Clause
# A scaling series where every camera sees many others: sbagen orbit scenes (cameras around
# the points, looking at their centre), 100 points per camera, tracks of 3..40 cameras, so
# that S is dense. Our chol, sparse-chol and iterative-schur beside Ceres ITERATIVE_SCHUR
# (SCHUR_JACOBI, Ceres's default options otherwise), 2 threads, at most 30 iterations.
# sparse-chol stops at 1000 cameras (about 20 s per iteration at 2000).
#
#   bench/orbit_series.sh [BUILD_DIR]
#
# Writes bench/results/orbit_series.json (sba_bench's JSON lines) and orbit_series.md (its
# tables and the commands). BUILD_DIR: a build with the bench (default build-bench/).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
build=${1:-"$root/build-bench"}
exe="$build/bench/sba_bench"
json="$here/results/orbit_series.json"
md="$here/results/orbit_series.md"
[ -x "$exe" ] || { echo "orbit_series: $exe not found (build the sba_bench target)" >&2; exit 1; }
rm -f "$json"
{
  echo "# Orbit scaling series: every camera sees many others"
  echo
  echo "Generated $(date -u '+%Y-%m-%d %H:%M UTC') on $(nproc) hardware threads by"
  echo "\`bench/orbit_series.sh\`. One run per configuration (wall times on a shared machine:"
  echo "compare ratios within one problem, not across runs); ms/iter is the solve's wall time"
  echo "over its iterations (sba: outer LM iterations; Ceres: LM steps tried); RSS is the"
  echo "child's peak resident set during the solve (program, inputs and solver)."
  echo
} > "$md"
for spec in "100 chol,sparse-chol,iterative-schur" "300 chol,sparse-chol,iterative-schur" \
            "1000 chol,sparse-chol,iterative-schur" "2000 chol,iterative-schur"; do
  set -- $spec
  cams=$1
  cmd="$exe --gen cameras=$cams,points=$((cams * 100)),track=3..40,trajectory=orbit,seed=7 \
--solvers $2 --ceres iterative --threads 2 --itmax 30 --timeout 900 --out $json"
  echo "## $cams cameras" >> "$md"
  echo >> "$md"
  echo "    $cmd" | sed "s|$root/||g" >> "$md"
  echo >> "$md"
  echo "\`\`\`" >> "$md"
  $cmd 2>&1 | grep -v '^sba_bench: .*\.\.\.' | tee -a "$md"
  echo "\`\`\`" >> "$md"
  echo >> "$md"
done
