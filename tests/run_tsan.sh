#!/bin/sh
# The threaded code under ThreadSanitizer: the threaded unit tests, and bin/i2m on a real
# image with 4 worker threads (the first run with the sliver perturbation on the tiles too).
# Any report fails (halt_on_error).  OMP_NUM_THREADS=1 keeps the
# distance transform's OpenMP loops on one thread (their implicit barriers are inside the
# uninstrumented OpenMP runtime); the worker team's own synchronisation is all visible.
set -u
cd "$(dirname "$0")/.."
export TSAN_OPTIONS="halt_on_error=1 exitcode=66 ${TSAN_OPTIONS:-}"
export OMP_NUM_THREADS=1
DATA=${I2M_DATA:-../shared/data}
fail=0
start=$(date +%s)
if build/tsan/tests/test_threads_refine >/tmp/i2m_tsan_unit.log 2>&1; then
  echo "  PASS  [tsan] test_threads_refine ($(( $(date +%s) - start )) s)"
else
  echo "  FAIL  [tsan] test_threads_refine"; tail -n 40 /tmp/i2m_tsan_unit.log; fail=1
fi
start=$(date +%s)
out=$(mktemp -d)
if build/tsan/bin/i2m "$DATA/spine_verse009.nii.gz" -o "$out/spine.vtu" --delta 2 --threads 4 --sliver-angle 5 --quiet >"$out/log" 2>&1 &&
   bin/i2m-check "$out/spine.vtu" --max-ratio 2 --min-facet-angle 30 >"$out/check" 2>&1; then
  echo "  PASS  [tsan] i2m on spine_verse009, 4 threads, sliver perturbation ($(( $(date +%s) - start )) s)"
else
  echo "  FAIL  [tsan] i2m on spine_verse009, 4 threads, sliver perturbation"; tail -n 40 "$out/log"; grep -E "VIOLATED|result" "$out/check"; fail=1
fi
start=$(date +%s)
if build/tsan/bin/i2m "$DATA/spine_verse009.nii.gz" -o "$out/spine_d.vtu" --delta 2 --threads 4 --deterministic --quiet >"$out/log" 2>&1 &&
   bin/i2m-check "$out/spine_d.vtu" --max-ratio 2 --min-facet-angle 30 >"$out/check" 2>&1; then
  echo "  PASS  [tsan] i2m on spine_verse009, 4 threads, deterministic mode ($(( $(date +%s) - start )) s)"
else
  echo "  FAIL  [tsan] i2m on spine_verse009, 4 threads, deterministic mode"; tail -n 40 "$out/log"; grep -E "VIOLATED|result" "$out/check"; fail=1
fi
rm -rf "$out"
exit $fail
