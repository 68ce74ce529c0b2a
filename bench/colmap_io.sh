#!/bin/sh
# SPDX-License-Identifier: BSD-3-Clause
# COLMAP model reading and writing against `colmap model_converter` (bench/README.md, "COLMAP
# model I/O"): makes a 2,000-image model with sbagen (text) and colmap model_converter (its
# binary twin) under BUILD_DIR/colmap_io/ unless it is there, runs colmap_io_bench on it and
# writes the table to bench/results/colmap_io.md.
#
#   bench/colmap_io.sh [BUILD_DIR] [--repeat N] [--before EXE [--before-sbarefine EXE]]
#
# BUILD_DIR (default build/) is a configured Release build with the bench (SBA_BUILD_BENCH=ON);
# the targets needed are built there. --before EXE adds the same table from another
# colmap_io_bench (one built at an earlier commit), run on the same model in the same session,
# with the sbarefine of that commit if --before-sbarefine names it.
set -eu

args="$*"
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
build=build
repeat=3
before=
before_sbarefine=
while [ $# -gt 0 ]; do
  case "$1" in
    --repeat) repeat=$2; shift 2 ;;
    --before) before=$2; shift 2 ;;
    --before-sbarefine) before_sbarefine=$2; shift 2 ;;
    -*) echo "usage: $0 [BUILD_DIR] [--repeat N] [--before EXE [--before-sbarefine EXE]]" >&2; exit 2 ;;
    *) build=$1; shift ;;
  esac
done
colmap=/usr/bin/colmap
if [ ! -x "$colmap" ]; then
  echo "$0: $colmap not found (Debian: colmap): nothing to compare with" >&2
  exit 1
fi

cmake --build "$build" --target colmap_io_bench sbarefine sbagen -j2
data="$build/colmap_io"
mkdir -p "$data/work" "$data/before"
# The model: a road of 2,000 cameras (OPENCV, one per image), 400,000 points seen by 2 to 10
# consecutive cameras, 2.4 million observations; 97 MB binary, 162 MB text.
if [ ! -f "$data/txt/points3D.txt" ] || [ ! -f "$data/bin/points3D.bin" ]; then
  rm -rf "$data/txt" "$data/bin"
  "$build/demo/sbagen" --out "$data/scene" --cameras 2000 --points 400000 --trajectory path \
    --track-min 2 --track-max 10 --kind varKD --colmap "$data/txt" >/dev/null
  mkdir -p "$data/bin"
  "$colmap" model_converter --input_path "$data/txt" --output_path "$data/bin" --output_type BIN >/dev/null 2>&1
fi

out="$root/bench/results/colmap_io.md"
load_before=$(cut -d' ' -f1-3 /proc/loadavg)
after_table=$("$build/bench/colmap_io_bench" --bin "$data/bin" --txt "$data/txt" --work "$data/work" \
  --repeat "$repeat" --sbarefine "$build/demo/sbarefine" --colmap "$colmap")
before_table=
if [ -n "$before" ]; then
  if [ -n "$before_sbarefine" ]; then
    before_table=$("$before" --bin "$data/bin" --txt "$data/txt" --work "$data/before" --repeat "$repeat" \
      --sbarefine "$before_sbarefine" --colmap none)
  else
    before_table=$("$before" --bin "$data/bin" --txt "$data/txt" --work "$data/before" --repeat "$repeat" \
      --colmap none)
  fi
fi
load_after=$(cut -d' ' -f1-3 /proc/loadavg)

# A rewrite is the model as read: the same bytes as the input in the same encoding, from
# write_model and from sbarefine; a conversion is the same bytes before and now.
differ() { echo "$0: $1 and $2 differ" >&2; exit 1; }
for f in cameras images points3D; do
  for w in sba sbarefine; do
    cmp -s "$data/bin/$f.bin" "$data/work/${w}_bin_bin/$f.bin" || differ "$data/bin/$f.bin" "$data/work/${w}_bin_bin/$f.bin"
    cmp -s "$data/txt/$f.txt" "$data/work/${w}_txt_txt/$f.txt" || differ "$data/txt/$f.txt" "$data/work/${w}_txt_txt/$f.txt"
  done
  if [ -n "$before" ]; then
    cmp -s "$data/before/sba_bin_txt/$f.txt" "$data/work/sba_bin_txt/$f.txt" || differ "$data/before/sba_bin_txt/$f.txt" "$data/work/sba_bin_txt/$f.txt"
    cmp -s "$data/before/sba_txt_bin/$f.bin" "$data/work/sba_txt_bin/$f.bin" || differ "$data/before/sba_txt_bin/$f.bin" "$data/work/sba_txt_bin/$f.bin"
  fi
done

{
  echo "# COLMAP model I/O against colmap model_converter"
  echo
  echo "Made by \`bench/colmap_io.sh $args\` on $(date -u +%Y-%m-%d), commit $(git -C "$root" rev-parse --short HEAD)"
  echo "($(nproc) cores, load average $load_before at the start, $load_after at the end; $(colmap -h 2>/dev/null | grep -m1 -o 'COLMAP [0-9.]*' || echo colmap))."
  echo "The model: \`sbagen --cameras 2000 --points 400000 --trajectory path --track-min 2 --track-max 10"
  echo "--kind varKD --colmap\`, 2,000 images (OPENCV cameras), 400,000 points, 2,399,894 observations;"
  echo "binary $(du -sm "$data/bin" | cut -f1) MB, text $(du -sm "$data/txt" | cut -f1) MB, in the page cache (each file was read just before)."
  echo
  echo "read_model and write_model run in colmap_io_bench's process (format_model: the formatting alone,"
  echo "in memory, part of write_model); sbarefine --itmax 0 and colmap model_converter are whole processes"
  echo "that read the model and write it in the other or the same encoding. sbarefine also builds the sba"
  echo "problem and scores its reprojection error in between."
  echo
  echo "## This commit"
  echo
  echo "$after_table"
  if [ -n "$before_table" ]; then
    echo
    echo "## Before (\`--before $before\`${before_sbarefine:+ \`--before-sbarefine $before_sbarefine\`})"
    echo
    echo "$before_table"
  fi
} > "$out"
cat "$out"
