#!/bin/sh
# Installs the Debian packages that the reliability checks need (see README, "Reliability"),
# on top of scripts/deps.sh test, when they are missing.
#   scripts/check_tools.sh valgrind   valgrind
#   scripts/check_tools.sh fuzz       clang-14 and its libFuzzer/sanitizer runtimes, bzip2
# Run as root it installs them with apt-get; otherwise it prints the exact command and fails.
set -eu

case "${1:-}" in
  valgrind) pkgs="valgrind" ;;
  fuzz) pkgs="clang-14 libclang-rt-14-dev bzip2 libbz2-dev" ;;
  *) echo "usage: $0 valgrind|fuzz" >&2; exit 2 ;;
esac

missing=""
for p in $pkgs; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing="$missing $p"
  fi
done
[ -z "$missing" ] && exit 0

if [ "$(id -u)" -eq 0 ]; then
  echo "check-tools: installing$missing" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends$missing >/dev/null
else
  echo "check-tools: missing Debian packages:$missing" >&2
  echo "check-tools: install them with: sudo apt-get install -y$missing" >&2
  exit 1
fi
