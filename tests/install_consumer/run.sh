#!/bin/sh
# Installs the built library into a scratch prefix and builds consumer.c and the C test of the
# 1.6 headers (../c_api_chkjac.c) against it: with find_package(sba) (shared and static), with
# pkg-config (shared), and with pkg-config --static against libsba.a alone, the way a 1.6
# Makefile links libsba.a; then runs them all.
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

# Static: a copy of the prefix without libsba.so, so that -lsba can only find libsba.a, and
# nothing on the link line but what pkg-config --static says.
static=$scratch/static-prefix
cp -R "$scratch/prefix" "$static"
rm -f "$static"/lib/libsba.so*
export PKG_CONFIG_PATH="$static/lib/pkgconfig"
libs=$(pkg-config --static --libs sba)
echo "install_consumer: pkg-config --static --libs sba: $libs"
# Libraries by name, as a 1.6 Makefile names them: a path to a .so would tie the line to one
# machine's layout (and to shared libraries).
for w in $libs; do
  case $w in
    -L* | -l* | -pthread) ;;
    *)
      echo "install_consumer: pkg-config --static --libs sba gives '$w', not an -l or -L flag" >&2
      exit 1
      ;;
  esac
done
case " $libs " in
  *" -lsba "*"-lstdc++ "*"-lm "*) ;;
  *)
    echo "install_consumer: pkg-config --static --libs sba lacks -lsba, -lstdc++ or -lm" >&2
    exit 1
    ;;
esac
cc -o "$scratch/consumer_pc_static" "$src/consumer.c" $(pkg-config --cflags sba) \
  $(pkg-config --static --libs sba)
cc -std=c99 -pedantic -Wall -Wextra -Werror -o "$scratch/chkjac_pc_static" "$src/../c_api_chkjac.c" \
  $(pkg-config --cflags sba) $(pkg-config --static --libs sba)
for exe in consumer_pc_static chkjac_pc_static; do
  if ldd "$scratch/$exe" | grep 'libsba\.so' >&2; then
    echo "install_consumer: $exe is linked against libsba.so, not libsba.a" >&2
    exit 1
  fi
done
"$scratch/consumer_pc_static"
"$scratch/chkjac_pc_static" "$scratch/chkjac.stderr" >/dev/null
echo "install_consumer: all programs built and ran"
