#!/bin/sh
# Bad parameters and hopeless inputs: bin/i2m ends with exactly one clear error line on
# stderr (naming the option or file and the problem), a non-zero exit that is not a crash,
# within a time limit; a tiny foreground still gives a valid mesh.  Run with the release
# binary and, when present, the ASan+UBSan one.
set -u
DATA=${I2M_DATA:-../shared/data}
TMP=${I2M_TMP:-$(mktemp -d)}
MK=${I2M_BIN:-bin}/i2m-mkimage
fail=0
"$MK" --shape ball --dims 24,20,16 --labels 3,7 -o "$TMP/ball.nrrd" >/dev/null
"$MK" --shape noise --labels 0 --dims 8,8,8 -o "$TMP/empty.nrrd" >/dev/null
"$MK" --shape speck --dims 20,20,20 -o "$TMP/speck.nrrd" >/dev/null
B="$TMP/ball.nrrd"

expect_error() { # binary, words expected in the message, then the arguments
  bin=$1; words=$2; shift 2
  timeout 120 "$bin" "$@" >"$TMP/out" 2>"$TMP/err"
  st=$?
  lines=$(wc -l <"$TMP/err")
  if [ $st -eq 0 ] || [ $st -ge 124 ] || [ "$lines" -ne 1 ]; then
    echo "FAIL ($bin $*): status $st, $lines stderr lines:"; cat "$TMP/err"; fail=1; return
  fi
  for w in $words; do
    grep -qi -- "$w" "$TMP/err" || { echo "FAIL ($*): message lacks '$w': $(cat "$TMP/err")"; fail=1; return; }
  done
  echo "ok   $(cat "$TMP/err")"
}

for bin in "${I2M_BIN:-bin}/i2m" build/asan/bin/i2m; do
  [ -x "$bin" ] || continue
  echo "== $bin"
  expect_error "$bin" "delta positive" "$B" -o "$TMP/o.vtu" --delta 0
  expect_error "$bin" "delta positive" "$B" -o "$TMP/o.vtu" --delta -1
  expect_error "$bin" "delta number" "$B" -o "$TMP/o.vtu" --delta abc
  expect_error "$bin" "size positive" "$B" -o "$TMP/o.vtu" --size 0
  expect_error "$bin" "ratio 2" "$B" -o "$TMP/o.vtu" --ratio 1.5
  expect_error "$bin" "facet-angle 30" "$B" -o "$TMP/o.vtu" --facet-angle 40
  expect_error "$bin" "region outside" "$B" -o "$TMP/o.vtu" --region 1000,1000,1000,1010,1010,1010:1
  expect_error "$bin" "region" "$B" -o "$TMP/o.vtu" --region 1,2,3:1
  expect_error "$bin" "size-label label 5" "$B" -o "$TMP/o.vtu" --size-label 5=1
  expect_error "$bin" "size-label" "$B" -o "$TMP/o.vtu" --size-label 3
  expect_error "$bin" "foreground" "$TMP/empty.nrrd" -o "$TMP/o.vtu"
  expect_error "$bin" "output format" "$B" -o "$TMP/o.stl"
  expect_error "$bin" "no output" "$B"
  expect_error "$bin" "input" -o "$TMP/o.vtu"
  expect_error "$bin" "unknown option" "$B" -o "$TMP/o.vtu" --frobnicate 3
  expect_error "$bin" "missing.nrrd" "$TMP/missing.nrrd" -o "$TMP/o.vtu"
  expect_error "$bin" "directory" "$TMP" -o "$TMP/o.vtu"
  expect_error "$bin" "o.vtu exist" "$B" -o "$TMP/no/such/dir/o.vtu"
  # a launcher says N processes but MPI sees one (another MPI's mpirun, or no MPI in this
  # build): each stops (no N copies writing one file); (the MPI library's own allocations at
  # exit are not ours for LeakSanitizer)
  ASAN_OPTIONS=detect_leaks=0 OMPI_COMM_WORLD_SIZE=4 expect_error "$bin" "4 MPI processes" "$B" -o "$TMP/o.vtu"
  ASAN_OPTIONS=detect_leaks=0 PMI_SIZE=2 expect_error "$bin" "2 MPI processes" "$B" -o "$TMP/o.vtu"
  # a single foreground voxel: a valid (tiny) mesh, quickly
  if timeout 60 "$bin" "$TMP/speck.nrrd" -o "$TMP/speck.vtu" --quiet &&
     "${I2M_BIN:-bin}/i2m-check" "$TMP/speck.vtu" --max-ratio 2 >/dev/null; then
    echo "ok   one-voxel image: valid mesh"
  else
    echo "FAIL one-voxel image"; fail=1
  fi
  # no --threads: OMP_NUM_THREADS decides, as for any OpenMP program
  if OMP_NUM_THREADS=3 timeout 60 "$bin" "$B" -o "$TMP/t.vtu" --report "$TMP/t.json" --quiet &&
     grep -q '"threads": 3' "$TMP/t.json"; then
    echo "ok   OMP_NUM_THREADS=3: 3 worker threads"
  else
    echo "FAIL OMP_NUM_THREADS=3 did not give 3 worker threads"; fail=1
  fi
  # a runtime that would give fewer threads than asked for (the team waits for all of them):
  # as many as allowed, never a hang, in both modes
  for env in OMP_THREAD_LIMIT=2 OMP_DYNAMIC=true; do
    for mode in "" --deterministic; do
      if env $env timeout 60 "$bin" "$B" -o "$TMP/t.vtu" --threads 4 $mode --report "$TMP/t.json" --quiet &&
         "${I2M_BIN:-bin}/i2m-check" "$TMP/t.vtu" --max-ratio 2 >/dev/null &&
         { [ $env != OMP_THREAD_LIMIT=2 ] || grep -q '"threads": 2' "$TMP/t.json"; }; then
        echo "ok   $env, --threads 4 $mode: valid mesh"
      else
        echo "FAIL $env, --threads 4 $mode: status $?, or no valid mesh, or not 2 threads under the limit"; fail=1
      fi
    done
  done
done
exit $fail
