#!/bin/sh
# MPI_THREAD_FUNNELED, checked: bin/i2m runs at 2 ranks x 2 worker threads (asynchronous mode
# and --deterministic) with the PMPI wrapper tests/mpi/pmpi_funneled.c preloaded into every
# rank; the wrapper aborts the job with one line naming the MPI function if any thread other
# than the one that called MPI_Init_thread calls MPI.  Asserted: exit 0, a mesh written, and
# each rank's count of the calls the wrapper saw (> 0: the wrapper was in the way).  The
# wrapper itself is checked first on a deliberately bad program (an MPI call from a second
# pthread): it must be caught, with the function named, and its good twin must pass.
# Builds nothing: the Makefile puts the wrapper and the bad program in build/release/tests
# (make mpi-tools; check-scripts builds them).  Skipped without mpirun.
set -u
BIN=${I2M_BIN:-bin}
TMP=${I2M_TMP:-$(mktemp -d)}
TOOLS=${I2M_MPI_TOOLS:-build/release/tests}
if ! command -v mpirun >/dev/null 2>&1; then
  echo "SKIP: no MPI (mpirun not found)"
  exit 0
fi
if [ ! -f "$TOOLS/pmpi_funneled.so" ] || [ ! -x "$TOOLS/funneled_bad" ]; then
  echo "FAIL: $TOOLS/pmpi_funneled.so or $TOOLS/funneled_bad missing (make mpi-tools)"
  exit 1
fi
WRAP="$(cd "$TOOLS" && pwd)/pmpi_funneled.so"
export OMPI_MCA_mpi_yield_when_idle=1
ROOT=""
[ "$(id -u)" = 0 ] && ROOT=--allow-run-as-root
run() { # ranks, then the program and its arguments; status in $st, stderr in $TMP/err
  np=$1; shift
  timeout 120 mpirun $ROOT --oversubscribe --bind-to none -np "$np" -x PMPI_FUNNELED_REPORT=1 -x OMP_NUM_THREADS=2 \
    -x LD_PRELOAD="$WRAP" "$@" >"$TMP/out" 2>"$TMP/err"
  st=$?
}
fail=0

# the wrapper on a program that breaks FUNNELED: caught, the function named
run 2 "$TOOLS/funneled_bad" bad
if [ $st -ne 0 ] && [ $st -ne 124 ] &&
   grep -q "pmpi_funneled: rank [01]: MPI_Comm_rank called from a thread other than the one that called MPI_Init_thread" "$TMP/err"; then
  echo "ok   an MPI call from a second thread is caught: $(grep -m1 pmpi_funneled "$TMP/err")"
else
  echo "FAIL the wrapper did not catch an MPI call from a second thread (status $st):"; cat "$TMP/err"; fail=1
fi
# its twin that keeps to FUNNELED: exit 0, the wrapper loaded (calls counted)
run 2 "$TOOLS/funneled_bad" good
if [ $st -eq 0 ] && [ "$(grep -c "pmpi_funneled: rank [01]: [1-9][0-9]* MPI calls" "$TMP/err")" -eq 2 ]; then
  echo "ok   the same calls from the main thread pass: $(grep -m1 pmpi_funneled "$TMP/err")"
else
  echo "FAIL the good program under the wrapper (status $st):"; cat "$TMP/err"; fail=1
fi

# bin/i2m, 2 ranks x 2 threads, both modes
"$BIN/i2m-mkimage" --shape shells --dims 48,48,48 -o "$TMP/img.nrrd" >/dev/null || { echo "FAIL i2m-mkimage"; exit 1; }
for mode in "" --deterministic; do
  rm -f "$TMP/out.vtu" "$TMP/r.json"
  run 2 "$BIN/i2m" "$TMP/img.nrrd" -o "$TMP/out.vtu" --quiet --depth 2 --threads 2 $mode --report "$TMP/r.json"
  calls=$(sed -n 's/^pmpi_funneled: rank \([01]\): \([0-9]*\) MPI calls, all on the thread of MPI_Init_thread$/\2/p' "$TMP/err")
  n=$(echo $calls | wc -w)
  if [ $st -eq 0 ] && [ "$n" -eq 2 ] && ! echo " $calls " | grep -q " 0 " && [ -s "$TMP/out.vtu" ] &&
     grep -q '"threads": 2, "ranks": 2' "$TMP/r.json"; then
    echo "ok   i2m ${mode:-(asynchronous)}, 2 ranks x 2 threads: every MPI call on the thread of MPI_Init_thread (calls per rank: $(echo $calls))"
  else
    echo "FAIL i2m ${mode:-(asynchronous)} under the wrapper: status $st, $n rank reports (calls: $calls)"; cat "$TMP/err"; fail=1
  fi
done
exit $fail
