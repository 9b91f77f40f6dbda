#!/bin/sh
# Runs every script test tests/scripts/test_*.sh from the project root; fails if any fails.
# Each script gets I2M_DATA (the real images, read only) and a private scratch directory, and
# I2M_TEST_TIMEOUT seconds (1200; the longest takes about 5 minutes): a hang fails its script
# at once instead of holding the run until CI's own limit.
set -u
cd "$(dirname "$0")/.."
export I2M_DATA="${I2M_DATA:-$(pwd)/../shared/data}"
export I2M_BIN="${I2M_BIN:-$(pwd)/bin}"
export PYTHON="${PYTHON:-/usr/bin/python3}"
LIMIT=${I2M_TEST_TIMEOUT:-1200}
fail=0; n=0
for t in tests/scripts/test_*.sh; do
  [ -f "$t" ] || continue
  n=$((n+1))
  scratch=$(mktemp -d)
  log="$scratch/log"
  start=$(date +%s)
  I2M_TMP="$scratch" timeout -k 10 "$LIMIT" sh "$t" >"$log" 2>&1
  rc=$?
  if [ $rc -eq 0 ]; then
    echo "  PASS  $(basename "$t") ($(( $(date +%s) - start )) s)"
  elif [ $rc -eq 124 ] || [ $rc -eq 137 ]; then
    echo "  FAIL  $(basename "$t") (timed out after $LIMIT s: a hang)"; tail -n 40 "$log"; fail=1
  else
    echo "  FAIL  $(basename "$t")"; tail -n 40 "$log"; fail=1
  fi
  rm -rf "$scratch"
done
echo "script tests: $n scripts, $( [ $fail = 0 ] && echo all passed || echo FAILURES)"
exit $fail
