#!/bin/sh
# SPDX-License-Identifier: BSD-3-Clause
# Installs the built library and programs into a scratch prefix, moves the prefix elsewhere
# (as a package built on another machine, or a conda environment, is), and then checks from
# the moved prefix only:
# - the installed programs start without LD_LIBRARY_PATH and answer --version;
# - the installed CMake package and sba.pc hold no path of the build machine or of the
#   prefix they were installed into;
# - consumer.c and the C test of the 1.6 headers (../c_api_chkjac.c) build and run with
#   find_package(sba) (shared and static), with pkg-config (shared), and with
#   pkg-config --static against libsba.a alone, the way a 1.6 Makefile links libsba.a.
# usage: run.sh BUILD_DIR SOURCE_DIR(of this script) SCRATCH_DIR
set -eu
build=$1 src=$2 scratch=$3
fail() {
  echo "install_consumer: $*" >&2
  exit 1
}
rm -rf "$scratch"
mkdir -p "$scratch"
cmake --install "$build" --prefix "$scratch/installed" >/dev/null
mv "$scratch/installed" "$scratch/prefix"
prefix=$scratch/prefix
for h in sba.h sba_ext.h sba_chkjac.h compiler.h; do
  [ -f "$prefix/include/$h" ] || fail "$h is not installed into include/"
done

unset LD_LIBRARY_PATH
for prog in eucsbademo balsba sbarefine sbagen; do
  [ -x "$prefix/bin/$prog" ] || fail "$prog is not installed into bin/"
  out=$("$prefix/bin/$prog" --version) || fail "the installed $prog --version failed"
  case $out in
    "$prog (sba "*")") ;;
    *) fail "the installed $prog --version printed '$out'" ;;
  esac
done

# Nothing installed may name the build tree, the prefix it was installed into, or a library
# file of the build machine: each is found again where the package is used.
for f in "$prefix"/lib/cmake/sba/*.cmake "$prefix/lib/pkgconfig/sba.pc"; do
  if grep -n -F -e "$scratch/installed" -e "$(cd "$build" && pwd)" "$f" >&2 ||
    grep -n -E '(^|[ ";=(])/[^ ";)]*\.(so|a)([.0-9]*)?([ ";)]|$)' "$f" >&2; then
    fail "$f holds a path of the machine it was built on"
  fi
done

cmake -S "$src" -B "$scratch/consumer" -DCMAKE_PREFIX_PATH="$prefix" >/dev/null
cmake --build "$scratch/consumer" >/dev/null
"$scratch/consumer/consumer_cmake"
"$scratch/consumer/consumer_static"
"$scratch/consumer/chkjac_cmake" "$scratch/chkjac.stderr" >/dev/null
"$scratch/consumer/chkjac_static" "$scratch/chkjac.stderr" >/dev/null
export PKG_CONFIG_PATH="$prefix/lib/pkgconfig"
[ "$(pkg-config --variable=prefix sba)" -ef "$prefix" ] ||
  fail "pkg-config's prefix of the moved sba.pc is $(pkg-config --variable=prefix sba), not $prefix"
cc -o "$scratch/consumer_pc" "$src/consumer.c" $(pkg-config --cflags --libs sba) -lm
LD_LIBRARY_PATH="$prefix/lib" "$scratch/consumer_pc"

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
