#!/bin/bash
# SPDX-License-Identifier: BSD-3-Clause
# Ctrl-C test of the MEX interface: an interactive octave-cli reads commands from a FIFO; a
# long solve is started and SIGINT is sent to the octave-cli process (what Ctrl-C does in a
# terminal). Octave must report the interruption, return to its prompt without a result,
# keep working (a new solve succeeds) and exit normally. Done twice: while the library runs
# slow C callbacks, and while the interpreter runs .m callbacks.
#   interrupt_test.sh OCTAVE_CLI TEST_SOURCE_DIR MEX_DIR
set -u
octave=$1 testdir=$2 mexdir=$3
if [ ! -f "${SBA_SHARED_DATA_DIR:-}/sba-demo/7cams.txt" ]; then
  echo "skipped: the shared data directory ${SBA_SHARED_DATA_DIR:-(unset)} is absent"
  exit 0
fi
work=$(mktemp -d)
fifo=$work/in out=$work/out
mkfifo "$fifo"
"$octave" --no-gui --norc --no-history --quiet --interactive --path "$testdir" --path "$mexdir" \
  <"$fifo" >"$out" 2>&1 &
pid=$!
exec 3>"$fifo"   # keeps Octave's stdin open between commands

fail() {
  echo "FAILED: $*"
  echo "---- octave output ----"
  cat "$out"
  exec 3>&-
  kill -KILL "$pid" 2>/dev/null
  rm -rf "$work"
  exit 1
}

# wait_for PATTERN SECONDS [COUNT]: until the output has COUNT (default 1) lines with PATTERN.
wait_for() {
  local t=0
  while [ "$(grep -c -F -- "$1" "$out")" -lt "${3:-1}" ]; do
    kill -0 "$pid" 2>/dev/null || fail "octave-cli exited while waiting for '$1'"
    sleep 0.2
    t=$((t + 1))
    [ "$t" -ge $(($2 * 5)) ] && fail "no '$1' after $2 s"
  done
}

round=0
for kind in lib m; do
  round=$((round + 1))
  echo "sbatest_long_solve('$kind')" >&3
  wait_for "LONG SOLVE STARTED ($kind)" 120
  sleep 3
  start=$(date +%s.%N)
  kill -INT "$pid"
  wait_for "sba: interrupted after" 60 "$round"
  stop=$(date +%s.%N)
  echo "$kind callbacks: interrupted; the solve stopped $(awk "BEGIN { printf \"%.3f\", $stop - $start }") s after SIGINT"
  grep -q "LONG SOLVE FINISHED ($kind)" "$out" && fail "the $kind solve ran to its end after SIGINT"
  echo "sbatest_after_interrupt('$kind')" >&3
  wait_for "AFTER INTERRUPT ($kind)" 120
  grep -q "AFTER INTERRUPT ($kind): OK" "$out" || fail "Octave misbehaves after the interrupt"
done

echo "exit(0)" >&3
exec 3>&-
wait "$pid"
status=$?
grep -i -E "segmentation|panic|fatal|core dumped" "$out" && fail "octave-cli crashed"
[ "$status" -eq 0 ] || fail "octave-cli exited with status $status"
echo "---- octave output ----"
cat "$out"
rm -rf "$work"
echo "interrupt test passed"
