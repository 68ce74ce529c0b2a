#!/bin/sh
# Installs the built library into a scratch prefix and builds consumer.c against it with
# find_package(sba) (shared and static) and with pkg-config, then runs all three.
# usage: run.sh BUILD_DIR SOURCE_DIR(of this script) SCRATCH_DIR
set -eu
build=$1 src=$2 scratch=$3
rm -rf "$scratch"
cmake --install "$build" --prefix "$scratch/prefix" >/dev/null
cmake -S "$src" -B "$scratch/consumer" -DCMAKE_PREFIX_PATH="$scratch/prefix" >/dev/null
cmake --build "$scratch/consumer" >/dev/null
LD_LIBRARY_PATH="$scratch/prefix/lib:${LD_LIBRARY_PATH:-}" "$scratch/consumer/consumer_cmake"
"$scratch/consumer/consumer_static"
PKG_CONFIG_PATH="$scratch/prefix/lib/pkgconfig" \
  cc -o "$scratch/consumer_pc" "$src/consumer.c" $(PKG_CONFIG_PATH="$scratch/prefix/lib/pkgconfig" pkg-config --cflags --libs sba) -lm
LD_LIBRARY_PATH="$scratch/prefix/lib:${LD_LIBRARY_PATH:-}" "$scratch/consumer_pc"
