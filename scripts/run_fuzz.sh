#!/bin/sh
# SPDX-License-Identifier: BSD-3-Clause
# make check-fuzz: runs every libFuzzer target of fuzz/ for a bounded time, seeded with the
# real input files, and fails if any of them finds a crash, a leak, a timeout, an
# out-of-memory or a broken promise (see fuzz/fuzz_common.h). The seed corpora are assembled
# at run time in a temporary directory from ../shared/data (the sba demo files and the BAL
# problems), the project's data/ and tests/fuzz_regressions/; nothing of them is kept. The
# option checks' targets (pysba_options, mex_options, camera_params) read no file format:
# they start from their regressions alone, steered by fuzz/options.dict.
#
# usage: scripts/run_fuzz.sh FUZZ_BUILD_DIR [SECONDS_PER_TARGET] [SHARED_DATA_DIR]
# Crashing inputs are kept in FUZZ_BUILD_DIR/artifacts/; to keep one as a regression test,
# copy it to tests/fuzz_regressions/TARGET-SHORT-NAME (see the README there). With
# SBA_FUZZ_KEEP_CORPUS=DIR the final corpora are copied to DIR/TARGET/ before cleaning up.
set -eu

build=$(cd "$1" && pwd)
seconds=${2:-60}
root=$(cd "$(dirname "$0")/.." && pwd)
shared=${3:-$root/../shared/data}

work=$(mktemp -d "${TMPDIR:-/tmp}/sba-fuzz.XXXXXX")
# The eucsbademo readers take paths: each input is written to a file there (in memory).
inputs=$(mktemp -d /dev/shm/sba-fuzz.XXXXXX 2>/dev/null || mktemp -d "$work/inputs.XXXXXX")
trap 'rm -rf "$work" "$inputs"' EXIT INT TERM
artifacts=$build/artifacts
mkdir -p "$artifacts"

seed() {  # seed TARGET FILE...: copies the files that exist into TARGET's corpus
  target=$1
  shift
  mkdir -p "$work/corpus-$target"
  for f in "$@"; do
    [ -f "$f" ] && cp "$f" "$work/corpus-$target/$(basename "$f")"
  done
  return 0
}

if [ ! -d "$shared" ]; then
  echo "check-fuzz: note: no shared data at $shared: seeding from data/ and tests/ only"
fi
seed cameras "$shared"/sba-demo/*cams*.txt "$root"/data/*-cams.txt
seed points "$shared"/sba-demo/*pts.txt "$root"/data/*-pts.txt
seed calibration "$shared"/sba-demo/calib.txt "$root"/data/*-calib.txt
seed bal "$shared"/bal/dubrovnik-3-7-pre.txt.bz2
# BAL text seeds: the smallest problem whole, and the beginnings of the others (they fail as
# truncated files, but carry real observation and camera lines).
for f in "$shared"/bal/*.txt.bz2; do
  [ -f "$f" ] || continue
  b=$(basename "$f" .bz2)
  case "$b" in
    dubrovnik-3-7-pre.txt) bzip2 -dc "$f" > "$work/corpus-bal/$b" ;;
    *) bzip2 -dc "$f" 2>/dev/null | head -c 8192 > "$work/corpus-bal/head-$b" || true ;;
  esac
done
# COLMAP, Bundler and NVM seeds: generated scenes (fuzz/seed_writer.cpp).
mkdir -p "$work/corpus-colmap" "$work/corpus-bundler" "$work/corpus-nvm"
"$build/seed_writer" "$work/corpus-colmap" "$work/corpus-bundler" "$work/corpus-nvm" >/dev/null
# Image lists (fuzz_hold_poses): a list of ids and names, all, and a file of names.
mkdir -p "$work/corpus-hold_poses"
printf '10,img_0.png,0' > "$work/corpus-hold_poses/ids-and-names"
printf 'all' > "$work/corpus-hold_poses/all"
printf 'a,b.png\r\n\n10\ndup.png' > "$work/corpus-hold_poses/names-file"
# Prior files (fuzz_priors): the first byte picks the kind (0 positions, 1 points, 2 intrinsics).
mkdir -p "$work/corpus-priors"
printf '\000a.png 1 2 3\nb.png 4 5 6 1 0 0 0 1 0 0 0 1 CARTESIAN\n10 47.1 8.2 400 WGS84\n' > "$work/corpus-priors/positions"
printf '\001100 1 2 3 0.5\n103 4 5 6 1 0 0 0 2 0 0 0 3\n' > "$work/corpus-priors/points"
printf '\0021 f 500 5\n2 fy 505 1\n2 4 0.1 0.01\n' > "$work/corpus-priors/intrinsics"
targets="cameras points calibration bal colmap bundler nvm hold_poses priors pysba_options mex_options camera_params"
# Earlier findings: tests/fuzz_regressions/TARGET-*.
for t in $targets; do
  seed "$t" "$root"/tests/fuzz_regressions/"$t"-*
done

fuzz() {  # fuzz TARGET: one target for the time given; its exit code in $work/TARGET.rc
  t=$1
  case "$t" in
    pysba_options|mex_options|camera_params) max_len=512 dict=options ;;
    points) max_len=16384 dict=eucsba ;;  # the seeds are cut to their first 16 KB
    bal) max_len=16384 dict=bal ;;
    colmap|bundler) max_len=16384 dict=colmap ;;
    nvm) max_len=16384 dict=nvm ;;
    hold_poses) max_len=1024 dict=hold_poses ;;
    priors) max_len=2048 dict=eucsba ;;
    *) max_len=4096 dict=eucsba ;;
  esac
  rc=0
  mkdir -p "$inputs/$t"
  SBA_FUZZ_TMPDIR=$inputs/$t "$build/fuzz_$t" -max_total_time="$seconds" -max_len="$max_len" \
    -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 -dict="$root/fuzz/$dict.dict" \
    -artifact_prefix="$artifacts/$t-" "$work/corpus-$t" >"$work/$t.log" 2>&1 || rc=$?
  echo "$rc" >"$work/$t.rc"
}

report() {  # report TARGET: its line, and its log's tail if it failed; returns its exit code
  t=$1
  log=$work/$t.log
  rc=$(cat "$work/$t.rc")
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -n 1 | cut -d' ' -f2)
  corpus=$(ls "$work/corpus-$t" | wc -l)
  if [ "$rc" -eq 0 ]; then
    echo "check-fuzz: fuzz_$t: ${runs:-?} inputs in ${seconds} s, coverage ${cov:-?}, corpus $corpus: no failure"
  else
    echo "check-fuzz: fuzz_$t: FAILED (exit $rc); the input is in $artifacts; log:"
    grep -v '^#[0-9]' "$log" | tail -n 60
  fi
  return "$rc"
}

# Each target is one process on one core: FUZZ_JOBS of them run at once (the machine's cores
# by default), each for the full time, so the run takes the time of the targets divided by
# the cores and fuzzes as long as one at a time would.
jobs=${FUZZ_JOBS:-$(nproc 2>/dev/null || echo 1)}
set -- $targets
while [ $# -gt 0 ]; do
  batch=
  while [ $# -gt 0 ] && [ "$(echo $batch | wc -w)" -lt "$jobs" ]; do
    batch="$batch $1"
    shift
  done
  for t in $batch; do
    fuzz "$t" &
  done
  wait
done
status=0
for t in $targets; do
  report "$t" || status=1
done
if [ -n "${SBA_FUZZ_KEEP_CORPUS:-}" ]; then
  for t in $targets; do
    mkdir -p "$SBA_FUZZ_KEEP_CORPUS/$t"
    cp "$work/corpus-$t"/* "$SBA_FUZZ_KEEP_CORPUS/$t/"
  done
  echo "check-fuzz: corpora kept in $SBA_FUZZ_KEEP_CORPUS"
fi
exit $status
