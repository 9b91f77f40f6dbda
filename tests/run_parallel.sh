#!/bin/sh
# Runs test commands a few at a time and reports each as it ends:
#
#   tests/run_parallel.sh LABEL LIMIT CMD...     (each CMD: a program or a .sh script)
#
# At most I2M_TEST_JOBS (default: the cores, at most 4) run at once, in the order given (put
# the longest first: a free slot takes the next one).  Each gets a private scratch directory
# in I2M_TMP and LIMIT seconds (0: none): a hang fails that test at once instead of holding
# the run until CI's own limit.  A PASS/FAIL line is printed when a test ends; each failed
# test's own FAIL lines (with the 4 lines after each) and the end of its log follow the
# summary, so that the logs of tests that ran side by side do not interleave.  Exit status: 0
# when every test passed.
set -u
if [ "${1:-}" = --one ]; then # (one test, run by xargs below)
  label=$2 limit=$3 results=$4 cmd=$5
  name=$(basename "$cmd")
  scratch=$(mktemp -d)
  start=$(date +%s)
  case $cmd in *.sh) set -- sh "$cmd" ;; *) set -- "$cmd" ;; esac
  if [ "$limit" -gt 0 ]; then set -- timeout -k 10 "$limit" "$@"; fi
  I2M_TMP="$scratch" "$@" >"$results/$name.log" 2>&1
  rc=$?
  took=$(($(date +%s) - start))
  if [ $rc -eq 0 ]; then
    echo "  PASS  ${label}$name ($took s)"
  elif [ "$limit" -gt 0 ] && { [ $rc -eq 124 ] || [ $rc -eq 137 ]; }; then
    echo "  FAIL  ${label}$name (timed out after $limit s: a hang)"
    touch "$results/$name.failed"
  else
    echo "  FAIL  ${label}$name (exit $rc, $took s)"
    touch "$results/$name.failed"
  fi
  rm -rf "$scratch"
  exit 0
fi

label=$1 limit=$2
shift 2
cores=$(getconf _NPROCESSORS_ONLN 2>/dev/null || echo 1)
[ "$cores" -gt 4 ] && cores=4
jobs=${I2M_TEST_JOBS:-$cores}
results=$(mktemp -d)
trap 'rm -rf "$results"' EXIT
n=$#
for cmd in "$@"; do printf '%s\n' "$cmd"; done |
  xargs -P "$jobs" -I CMD sh "$0" --one "$label" "$limit" "$results" CMD
fail=0
for cmd in "$@"; do
  name=$(basename "$cmd")
  [ -f "$results/$name.failed" ] || continue
  fail=1
  if grep -q '^FAIL' "$results/$name.log"; then # (a script's own FAIL lines may lie far above its end)
    echo "---- $name's FAIL lines:"
    grep -A 4 '^FAIL' "$results/$name.log" | head -n 60
  fi
  echo "---- the end of $name's log:"
  tail -n 40 "$results/$name.log"
done
exit $fail
