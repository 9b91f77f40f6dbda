#!/bin/sh
# Error paths under mpirun: every case ends with a non-zero exit from mpirun, within a time
# limit (120 s; reaching it is a hang, and a failure), with no i2m process left behind.
#   (a) an input file that does not exist, at 2 and 4 ranks: one clear error line (i2m: ...),
#       naming the file, its rank prefix not repeated;
#   (b) a bad option on one rank only (MPMD: the other ranks' command lines are good), at
#       1+1 and 3+1 ranks: one error line naming the option;
#   (c) I2M_INJECT_FAILURE=1: rank 1 fails after its 3rd batch of tasks, in the middle of
#       the distributed refinement; asynchronous mode at 2, 3, 4 ranks and 2 ranks x 2
#       threads, --deterministic at 2 and 4 ranks: it must fail every time, with one line
#       that mentions the injected failure;
#   (d) a rank killed from outside (kill -9) while the knee atlas is meshed at 4 ranks x 1
#       thread: rank 1 after ~3 s, rank 0 after ~8 s (refining): mpirun must end non-zero
#       soon after, and no rank may be left running.
# Skipped ("SKIP: no MPI") when mpirun is missing.  About 45 s on 2 cores.
set -u
BIN=${I2M_BIN:-bin}
DATA=${I2M_DATA:-../shared/data}
TMP=${I2M_TMP:-$(mktemp -d)}
LIMIT=120
if ! command -v mpirun >/dev/null 2>&1; then
  echo "SKIP: no MPI (mpirun not found)"
  exit 0
fi
export OMPI_MCA_mpi_yield_when_idle=1
ROOT=""
[ "$(id -u)" = 0 ] && ROOT=--allow-run-as-root
fail=0
"$BIN/i2m-mkimage" --shape shells --dims 48,48,48 -o "$TMP/img.nrrd" >/dev/null || { echo "FAIL i2m-mkimage"; exit 1; }
IMG="$TMP/img.nrrd"

# mpirun with the given arguments under the time limit: status in $st, seconds in $secs
run_mpi() {
  t0=$(date +%s)
  timeout -k 10 $LIMIT mpirun $ROOT --oversubscribe --bind-to none "$@" >"$TMP/out" 2>"$TMP/err"
  st=$?
  secs=$(( $(date +%s) - t0 ))
}

# i2m processes still running whose command line holds $1 (not mpirun's or timeout's)
leftovers() { pgrep -f "^[^ ]*i2m .*$1" 2>/dev/null; }

# After run_mpi: non-zero, no hang, exactly one "i2m:" line holding every word of $2.
expect_error() {
  what=$1; words=$2
  lines=$(grep -c '^i2m: ' "$TMP/err")
  if [ $st -eq 124 ] || [ $secs -ge $LIMIT ]; then
    echo "FAIL $what: no end within $LIMIT s (a hang)"; fail=1; return
  fi
  if [ $st -eq 0 ] || [ "$lines" -ne 1 ]; then
    echo "FAIL $what: status $st, $lines i2m error lines:"; cat "$TMP/err"; fail=1; return
  fi
  for w in $words; do
    grep '^i2m: ' "$TMP/err" | grep -qi -- "$w" || {
      echo "FAIL $what: the message lacks '$w': $(grep '^i2m: ' "$TMP/err")"; fail=1; return; }
  done
  if grep '^i2m: ' "$TMP/err" | grep -Eq '\[rank [0-9]+\] \[rank [0-9]+\]'; then
    echo "FAIL $what: the rank prefix comes twice: $(grep '^i2m: ' "$TMP/err")"; fail=1; return
  fi
  echo "ok   $what (status $st, $secs s): $(grep '^i2m: ' "$TMP/err")"
}

# (a) a file that does not exist
for np in 2 4; do
  run_mpi -np $np "$BIN/i2m" "$TMP/no-such-image.nrrd" -o "$TMP/a.vtu" --quiet
  expect_error "(a) missing input, $np ranks" "no-such-image.nrrd no.such.file"
done

# (b) a bad option on one rank only
run_mpi -np 1 "$BIN/i2m" "$IMG" -o "$TMP/b.vtu" --quiet : -np 1 "$BIN/i2m" "$IMG" -o "$TMP/b.vtu" --quiet --bogus-option
expect_error "(b) --bogus-option on rank 1 of 2" "--bogus-option"
run_mpi -np 3 "$BIN/i2m" "$IMG" -o "$TMP/b.vtu" --quiet : -np 1 "$BIN/i2m" "$IMG" -o "$TMP/b.vtu" --quiet --bogus-option 7
expect_error "(b) --bogus-option 7 on rank 3 of 4" "unknown --bogus-option rank.3"

# (c) an injected failure on rank 1 in the middle of refinement, every time
for c in "2 1" "2 1" "3 1" "4 1" "2 2" "2 1 --deterministic" "4 1 --deterministic"; do
  set -- $c
  np=$1; T=$2; mode=${3:-}
  run_mpi -np "$np" -x I2M_INJECT_FAILURE=1 -x OMP_NUM_THREADS="$T" "$BIN/i2m" "$IMG" -o "$TMP/c.vtu" --quiet \
    --depth 2 --threads "$T" $mode
  if [ $st -eq 0 ] && ! grep -q injected "$TMP/err"; then
    echo "FAIL (c) $np ranks x $T threads ${mode:-asynchronous}: exit 0, the injected failure never fired"; fail=1
    continue
  fi
  expect_error "(c) injected failure, $np ranks x $T threads ${mode:-asynchronous}" "injected rank.1"
done

# (d) a rank killed from outside
IMGD="$DATA/knee_atlas.nrrd"; EXTRA="" # (about 40 s at 4 ranks x 1 thread)
if [ ! -f "$IMGD" ]; then            # (without the data: about 19 s)
  IMGD="$TMP/big.nrrd"; EXTRA="--delta 0.35"
  "$BIN/i2m-mkimage" --shape shells --dims 128,128,128 -o "$IMGD" >/dev/null
fi
for c in "1 3" "0 8"; do
  set -- $c
  victim_rank=$1; delay=$2
  OUT="$TMP/killed-$$-$victim_rank.vtu"
  t0=$(date +%s)
  timeout -k 10 $LIMIT mpirun $ROOT --oversubscribe --bind-to none -np 4 -x OMP_NUM_THREADS=1 \
    "$BIN/i2m" "$IMGD" -o "$OUT" --quiet --threads 1 $EXTRA >"$TMP/out" 2>"$TMP/err" &
  job=$!
  sleep "$delay"
  victim=""
  for p in $(leftovers "$OUT"); do
    tr '\0' '\n' <"/proc/$p/environ" 2>/dev/null | grep -qx "OMPI_COMM_WORLD_RANK=$victim_rank" && victim=$p
  done
  [ -z "$victim" ] && victim=$(leftovers "$OUT" | head -n 1)
  if [ -z "$victim" ]; then
    wait $job
    echo "FAIL (d) no i2m process to kill after $delay s (status $?): the run ended too soon"; cat "$TMP/err"; fail=1
    continue
  fi
  tk=$(date +%s)
  kill -9 "$victim"
  wait $job
  st=$?
  now=$(date +%s)
  sleep 1
  left=$(leftovers "$OUT")
  if [ -n "$left" ]; then
    echo "FAIL (d) rank $victim_rank killed: i2m processes left running: $left"; fail=1
    for p in $left; do kill -9 "$p" 2>/dev/null; done
  elif [ $st -eq 124 ] || [ $((now - t0)) -ge $LIMIT ]; then
    echo "FAIL (d) rank $victim_rank killed after $delay s: mpirun did not end within $LIMIT s (a hang)"; fail=1
  elif [ $st -eq 0 ]; then
    echo "FAIL (d) rank $victim_rank killed after $delay s: mpirun exited 0"; fail=1
  else
    echo "ok   (d) rank $victim_rank (pid $victim) killed after $delay s: mpirun ended with status $st $((now - tk)) s later, no rank left"
  fi
done
exit $fail
