#!/bin/sh
# SPDX-License-Identifier: BSD-3-Clause
# Installs the Debian packages that sba needs for a purpose, when they are missing.
#   scripts/deps.sh build   compiler, CMake, LAPACK/BLAS (OpenBLAS), SuiteSparse, bzip2
#   scripts/deps.sh bench   build + Ceres Solver, Google Benchmark and gnuplot (bench/)
#   scripts/deps.sh test    build + GoogleTest + GNU Octave (the MEX interface's tests) + python,
#                           and COLMAP (tests/colmap_real) if it installs: optional, its tests skip without it;
#                           then a venv with pycolmap from PyPI (tests/pycolmap) at $SBA_PYCOLMAP_VENV
#                           (default build/pycolmap-venv) if it is not there: optional too
#   scripts/deps.sh python  build + what the Python package pysba builds and tests with
#   scripts/deps.sh mex     build + GNU Octave with its MEX headers
#   scripts/deps.sh valgrind  build + valgrind (make check-valgrind)
#   scripts/deps.sh fuzz    build + clang-14 with its libFuzzer/sanitizer runtimes (make check-fuzz)
# Run as root it installs them with apt-get; otherwise it prints the exact command and fails.
# An optional package that is missing or fails to install is reported, never a failure: COLMAP
# pulls in a large GUI stack and is absent from some releases, and only tests that skip need it.
set -eu

purpose=${1:-build}
pkgs="g++ make cmake pkg-config liblapack-dev libblas-dev libopenblas-dev libsuitesparse-dev libbz2-dev libsqlite3-dev"
# python3-pybind11 and the .whl packages: the test of `pip install .` with build isolation
# builds its wheelhouse from them (tests/python/test_install.py).
python_pkgs="python3-dev pybind11-dev python3-numpy python3-pytest python3-venv python3-setuptools python3-pip
python3-wheel python3-pybind11 python3-setuptools-whl python3-wheel-whl"
optional=""
case "$purpose" in
  build) ;;
  test)
    pkgs="$pkgs libgtest-dev octave octave-dev $python_pkgs"
    optional="colmap" ;;
  python) pkgs="$pkgs $python_pkgs" ;;
  mex) pkgs="$pkgs octave octave-dev" ;;
  bench) pkgs="$pkgs libceres-dev libbenchmark-dev gnuplot-nox" ;;
  valgrind) pkgs="$pkgs valgrind" ;;
  fuzz) pkgs="$pkgs clang-14 libclang-rt-14-dev bzip2" ;;
  *) echo "usage: $0 build|test|python|mex|bench|valgrind|fuzz" >&2; exit 2 ;;
esac

# The venv of tests/pycolmap: made when missing, with the pycolmap its tests were written against.
# Without PyPI (offline, a proxy) it is reported and left out, and those tests skip: never a
# failure. A venv that pip could not fill is removed, so that the next run tries again.
PYCOLMAP=pycolmap==4.2.1
pycolmap_venv() {
  venv=${SBA_PYCOLMAP_VENV:-$(dirname "$0")/../build/pycolmap-venv}
  "$venv/bin/python3" -c 'import pycolmap' 2>/dev/null && return 0
  echo "deps: making $venv with $PYCOLMAP from PyPI (tests/pycolmap)" >&2
  rm -rf "$venv"
  if python3 -m venv "$venv" >/dev/null &&
     "$venv/bin/python3" -m pip install -q --disable-pip-version-check --retries 2 --timeout 30 "$PYCOLMAP" &&
     "$venv/bin/python3" -c 'import pycolmap'; then
    return 0
  fi
  rm -rf "$venv"
  echo "deps: optional $PYCOLMAP did not install; the tests that need it (tests/pycolmap) will skip" >&2
}

# not_installed PKG...: the ones dpkg does not list as installed.
not_installed() {
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || printf ' %s' "$p"
  done
}
# shellcheck disable=SC2086  # the package lists are split on purpose
missing=$(not_installed $pkgs)
# shellcheck disable=SC2086
missing_optional=$(not_installed $optional)
if [ -z "$missing$missing_optional" ]; then
  [ "$purpose" = test ] && pycolmap_venv
  exit 0
fi

if [ "$(id -u)" -eq 0 ]; then
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  if [ -n "$missing" ]; then
    echo "deps: installing$missing" >&2
    apt-get install -y -qq --no-install-recommends$missing >/dev/null
  fi
  if [ -n "$missing_optional" ]; then
    echo "deps: installing (optional)$missing_optional" >&2
    apt-get install -y -qq --no-install-recommends$missing_optional >/dev/null ||
      echo "deps: optional$missing_optional did not install; the tests that need it will skip" >&2
  fi
else
  [ -n "$missing_optional" ] &&
    echo "deps: optional, missing:$missing_optional (the tests that need it skip); sudo apt-get install -y$missing_optional" >&2
  if [ -n "$missing" ]; then
    echo "deps: missing Debian packages:$missing" >&2
    echo "deps: install them with: sudo apt-get install -y$missing" >&2
    exit 1
  fi
fi
[ "$purpose" = test ] && pycolmap_venv
exit 0
