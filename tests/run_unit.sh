#!/bin/sh
# Runs every CUnit test program in $1 (built for configuration $2); fails if any fails.
set -u
dir=$1; cfg=$2
fail=0; n=0
export I2M_DATA="${I2M_DATA:-$(cd "$(dirname "$0")/.." && pwd)/../shared/data}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1}"
for t in "$dir"/test_*; do
  [ -x "$t" ] || continue
  n=$((n+1))
  log=$(mktemp)
  start=$(date +%s)
  if "$t" >"$log" 2>&1; then
    echo "  PASS  [$cfg] $(basename "$t") ($(( $(date +%s) - start )) s)"
  else
    echo "  FAIL  [$cfg] $(basename "$t")"; tail -n 40 "$log"; fail=1
  fi
  rm -f "$log"
done
echo "unit tests [$cfg]: $n programs, $( [ $fail = 0 ] && echo all passed || echo FAILURES)"
exit $fail
