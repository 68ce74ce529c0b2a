#!/bin/sh
# SPDX-License-Identifier: BSD-3-Clause
# A large COLMAP sparse model for benchmarks of reading and writing models: sbagen's scene of
# 2,000 images and 400,000 points seen by 2..10 images each (about 2.4 million observations),
# as COLMAP text (written by sbagen) and binary (written by colmap model_converter, so that the
# binary model is one COLMAP wrote), and model_analyzer's counts of the binary one.
#
#   bench/colmap_io_model.sh OUTDIR [SBAGEN] [KIND]
#
# SBAGEN: the sbagen program (default build/demo/sbagen); KIND: sbagen's --kind, varKD (the
# default: an OPENCV camera per image, which sbarefine reads today), varK (PINHOLE per image)
# or fixed (one PINHOLE camera shared by every image). The scene depends only on the options
# here (seed 36): the same command makes the same model.
# Writes OUTDIR/text (157 MB), OUTDIR/binary (93 MB) and OUTDIR/counts.txt; about 20 s of CPU.
set -eu

[ $# -ge 1 ] || { echo "usage: $0 OUTDIR [SBAGEN] [KIND]" >&2; exit 2; }
out=$1
sbagen=${2:-build/demo/sbagen}
kind=${3:-varKD}
colmap=${COLMAP:-$(command -v colmap || echo /usr/bin/colmap)}
[ -x "$sbagen" ] || { echo "$0: no sbagen program at $sbagen (build the target sbagen)" >&2; exit 1; }
[ -x "$colmap" ] || { echo "$0: no colmap program at $colmap (scripts/deps.sh test installs it)" >&2; exit 1; }

mkdir -p "$out/binary"
"$sbagen" --out "$out/sbagen" --colmap "$out/text" --kind "$kind" --cameras 2000 --points 400000 \
  --track-min 2 --track-max 10 --seed 36
"$colmap" model_converter --input_path "$out/text" --output_path "$out/binary" --output_type BIN
# sbagen's own files (PREFIX-cams.txt ...) are not the model: only the COLMAP directories stay.
rm -f "$out"/sbagen-*
"$colmap" model_analyzer --path "$out/binary" 2>&1 | grep -E 'Cameras|Images|Points|Observations' \
  | sed 's/^.*\] //' | tee "$out/counts.txt"
du -sh "$out/text" "$out/binary"
