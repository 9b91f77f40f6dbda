#!/bin/sh
# Runs every script test tests/scripts/test_*.sh from the project root; fails if any fails.
# Each script gets I2M_DATA (the real images, read only) and a private scratch directory.
set -u
cd "$(dirname "$0")/.."
export I2M_DATA="${I2M_DATA:-$(pwd)/../shared/data}"
export I2M_BIN="${I2M_BIN:-$(pwd)/bin}"
export PYTHON="${PYTHON:-/usr/bin/python3}"
fail=0; n=0
for t in tests/scripts/test_*.sh; do
  [ -f "$t" ] || continue
  n=$((n+1))
  scratch=$(mktemp -d)
  log="$scratch/log"
  start=$(date +%s)
  if I2M_TMP="$scratch" sh "$t" >"$log" 2>&1; then
    echo "  PASS  $(basename "$t") ($(( $(date +%s) - start )) s)"
  else
    echo "  FAIL  $(basename "$t")"; tail -n 40 "$log"; fail=1
  fi
  rm -rf "$scratch"
done
echo "script tests: $n scripts, $( [ $fail = 0 ] && echo all passed || echo FAILURES)"
exit $fail
