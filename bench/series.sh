#!/bin/sh
# SPDX-License-Identifier: BSD-3-Clause
# Scaling series where every camera sees many others (S dense), 100 points per camera, 2
# threads, at most 30 iterations, our solvers beside Ceres ITERATIVE_SCHUR (SCHUR_JACOBI,
# Ceres's default options otherwise):
#
#   orbit: sbagen orbit scenes (cameras around the points, looking at their centre), tracks of
#          3..40 cameras, 100 to 2000 cameras; chol, sparse-chol (to 1000 cameras, about 20 s
#          per iteration at 2000) and iterative-schur.
#   photo: sbagen photo collections (clusters of cameras at many distances on the front of a
#          landmark, heavy-tailed tracks from 4 cameras, a mean of 10 to 15), 100 to 10,000
#          cameras; chol where a dense S fits and factors in seconds (to 1000 cameras), and
#          iterative-schur with both LM strategies; Ceres SPARSE_SCHUR as well up to 300.
#
#   bench/series.sh orbit|photo [BUILD_DIR]
#
# Writes bench/results/NAME_series.json (sba_bench's JSON lines) and NAME_series.md (its
# tables and the commands). BUILD_DIR: a build with the bench (default build-bench/).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
name=${1:-}
build=${2:-"$root/build-bench"}
exe="$build/bench/sba_bench"
case "$name" in
  orbit)
    title="Orbit scaling series: every camera sees many others"
    specs="100:chol,sparse-chol,iterative-schur:sba:iterative
           300:chol,sparse-chol,iterative-schur:sba:iterative
           1000:chol,sparse-chol,iterative-schur:sba:iterative
           2000:chol,iterative-schur:sba:iterative" ;;
  photo)
    title="Photo-collection scaling series: clusters of cameras around a landmark"
    specs="100:chol,iterative-schur:sba,trust-region:iterative,sparse
           300:chol,iterative-schur:sba,trust-region:iterative,sparse
           1000:chol,iterative-schur:sba,trust-region:iterative
           3000:iterative-schur:sba,trust-region:iterative
           10000:iterative-schur:sba,trust-region:iterative" ;;
  *) echo "usage: bench/series.sh orbit|photo [BUILD_DIR]" >&2; exit 2 ;;
esac
json="$here/results/${name}_series.json"
md="$here/results/${name}_series.md"
[ -x "$exe" ] || { echo "series: $exe not found (build the sba_bench target)" >&2; exit 1; }
rm -f "$json"
{
  echo "# $title"
  echo
  echo "Generated $(date -u '+%Y-%m-%d %H:%M UTC') on $(nproc) hardware threads by"
  echo "\`bench/series.sh $name\`. One run per configuration (wall times on a shared machine:"
  echo "compare ratios within one problem, not across runs); ms/iter is the solve's wall time"
  echo "over its iterations (sba: outer LM iterations; Ceres: LM steps tried); RSS is the"
  echo "child's peak resident set during the solve (program, inputs and solver)."
  echo
} > "$md"
for spec in $specs; do
  IFS=: read -r cams solvers strategies ceres <<EOS
$spec
EOS
  if [ "$name" = orbit ]; then
    scene="cameras=$cams,points=$((cams * 100)),track=3..40,trajectory=orbit,seed=7"
  else
    # Tracks up to 300 cameras: longer ones are rare in the tail, and n * track_max must fit
    # sba's int counts.
    scene="cameras=$cams,points=$((cams * 100)),track=4..$((cams < 300 ? cams : 300)),trajectory=photo,seed=7"
  fi
  cmd="$exe --gen $scene --solvers $solvers --strategy $strategies --ceres $ceres --threads 2 \
--itmax 30 --timeout 1800 --out $json"
  echo "## $cams cameras" >> "$md"
  echo >> "$md"
  echo "    $cmd" | sed "s|$root/||g" >> "$md"
  echo >> "$md"
  echo "\`\`\`" >> "$md"
  $cmd 2>&1 | grep -v '^sba_bench: .*\.\.\.' | tee -a "$md"
  echo "\`\`\`" >> "$md"
  echo >> "$md"
done
python3 "$here/plot_series.py" "$name"
