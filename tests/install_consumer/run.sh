#!/bin/sh
# Installs the built library into a scratch prefix and builds consumer.c and the C test of the
# 1.6 headers (../c_api_chkjac.c) against it: with find_package(sba) (shared and static) and
# with pkg-config; then runs them all.
# usage: run.sh BUILD_DIR SOURCE_DIR(of this script) SCRATCH_DIR
set -eu
build=$1 src=$2 scratch=$3
rm -rf "$scratch"
cmake --install "$build" --prefix "$scratch/prefix" >/dev/null
for h in sba.h sba_ext.h sba_chkjac.h compiler.h; do
  if [ ! -f "$scratch/prefix/include/$h" ]; then
    echo "install_consumer: $h is not installed into include/" >&2
    exit 1
  fi
done
cmake -S "$src" -B "$scratch/consumer" -DCMAKE_PREFIX_PATH="$scratch/prefix" >/dev/null
cmake --build "$scratch/consumer" >/dev/null
LD_LIBRARY_PATH="$scratch/prefix/lib:${LD_LIBRARY_PATH:-}" "$scratch/consumer/consumer_cmake"
"$scratch/consumer/consumer_static"
LD_LIBRARY_PATH="$scratch/prefix/lib:${LD_LIBRARY_PATH:-}" \
  "$scratch/consumer/chkjac_cmake" "$scratch/chkjac.stderr" >/dev/null
"$scratch/consumer/chkjac_static" "$scratch/chkjac.stderr" >/dev/null
PKG_CONFIG_PATH="$scratch/prefix/lib/pkgconfig" \
  cc -o "$scratch/consumer_pc" "$src/consumer.c" $(PKG_CONFIG_PATH="$scratch/prefix/lib/pkgconfig" pkg-config --cflags --libs sba) -lm
LD_LIBRARY_PATH="$scratch/prefix/lib:${LD_LIBRARY_PATH:-}" "$scratch/consumer_pc"

echo "install_consumer: all programs built and ran"
