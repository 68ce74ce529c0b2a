#!/bin/sh
# SPDX-License-Identifier: BSD-3-Clause
# make check-valgrind: one run of eucsbademo on a small generated problem under valgrind's
# memcheck; fails on any memory error and on any definite, indirect or possible leak.
# (Still-reachable blocks are the libraries' own one-time allocations: listed, not errors.)
#
# usage: scripts/check_valgrind.sh EUCSBADEMO PROBLEM_PREFIX
#   PROBLEM_PREFIX: e.g. data/orbit-fixedK (the -cams.txt, -pts.txt, -calib.txt files)
set -eu

demo=$1
problem=$2
log=$(mktemp "${TMPDIR:-/tmp}/sba-valgrind.XXXXXX")
trap 'rm -f "$log"' EXIT

set -- "$problem-cams.txt" "$problem-pts.txt"
[ -f "$problem-calib.txt" ] && set -- "$@" "$problem-calib.txt"
rc=0
valgrind --tool=memcheck --leak-check=full --show-leak-kinds=definite,indirect,possible \
  --errors-for-leak-kinds=definite,indirect,possible --track-origins=yes --error-exitcode=1 \
  --log-file="$log" "$demo" "$@" || rc=$?
grep -E "ERROR SUMMARY|definitely lost|indirectly lost|possibly lost|still reachable|All heap blocks" "$log" |
  sed 's/^==[0-9]*== */check-valgrind: /'
if [ "$rc" -ne 0 ]; then
  echo "check-valgrind: FAILED (exit $rc); valgrind's report:"
  cat "$log"
  exit 1
fi
echo "check-valgrind: eucsbademo $problem: no memory error, no leak"
