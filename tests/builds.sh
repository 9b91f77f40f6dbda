#!/bin/sh
# make check-builds: the other toolchains, each in its own build directory (see the Makefile),
# when its compiler is installed: MPICH (make MPI=mpich, run under mpirun.mpich), clang with
# the default MPI (make CC=clang), plain cc without MPI (make CC=cc HAVE_MPI=0, one process).
# Each builds warning-free (WERROR=1), meshes a 48^3 synthetic image of nested shells (two
# ranks under MPI, writing one stitched .vtu) and passes i2m-check.  About 20 s per
# toolchain on 2 cores (the last step of make check).
set -u
cd "$(dirname "$0")/.." || exit 2
JOBS=${JOBS:-2}
# each build gets its own toolchain variables only (make exports those of its command line)
unset MAKEFLAGS MFLAGS MAKEOVERRIDES CC MPI MPICC HAVE_MPI MPIRUN
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
fail=0
# name | make variables | compiler that must exist | launcher (empty: a plain process)
for spec in "mpich|MPI=mpich|mpicc.mpich|mpirun.mpich" "clang|CC=clang|clang|mpirun" "cc-nompi|CC=cc HAVE_MPI=0|cc|"; do
  name=${spec%%|*}; rest=${spec#*|}
  vars=${rest%%|*}; rest=${rest#*|}
  compiler=${rest%%|*}; launcher=${rest#*|}
  if ! command -v "$compiler" >/dev/null 2>&1 || { [ -n "$launcher" ] && ! command -v "$launcher" >/dev/null 2>&1; }; then
    echo "  SKIP  $name ($compiler${launcher:+ or $launcher} not installed)"
    continue
  fi
  printf '#include <omp.h>\nint main(void) { return omp_get_max_threads() < 1; }\n' >"$TMP/omp.c"
  if ! "$compiler" -fopenmp "$TMP/omp.c" -o "$TMP/omp" >/dev/null 2>&1; then
    echo "  SKIP  $name ($compiler has no OpenMP: for clang, apt-get install libomp-dev)"
    continue
  fi
  start=$(date +%s)
  log=$TMP/$name.log
  # shellcheck disable=SC2086
  if ! make --no-print-directory -j"$JOBS" WERROR=1 $vars programs >"$log" 2>&1; then
    echo "  FAIL  $name: make $vars"; grep -E "error|warning" "$log" | head -n 20; tail -n 5 "$log"; fail=1; continue
  fi
  # shellcheck disable=SC2086
  bindir=$(make --no-print-directory -s $vars print-BINDIR)
  out=$TMP/$name.vtu
  ok=1
  "$bindir/i2m-mkimage" --shape shells --dims 48,48,48 -o "$TMP/$name.nrrd" >>"$log" 2>&1 || ok=0
  if [ $ok = 1 ] && [ -n "$launcher" ]; then
    MPIRUN=$launcher I2M=$bindir/i2m sh run/mpirun.sh -n 2 -t 1 "$TMP/$name.nrrd" "$out" --depth 2 --quiet >>"$log" 2>&1 || ok=0
  elif [ $ok = 1 ]; then
    "$bindir/i2m" "$TMP/$name.nrrd" -o "$out" --threads 1 --quiet >>"$log" 2>&1 || ok=0
  fi
  [ $ok = 1 ] && { "$bindir/i2m-check" "$out" --max-ratio 2 >>"$log" 2>&1 || ok=0; }
  if [ $ok = 1 ]; then
    echo "  PASS  $name: $bindir/i2m ($(grep -o '[0-9]* tetrahedra' "$log" | head -n 1), $(( $(date +%s) - start )) s)"
  else
    echo "  FAIL  $name: meshing with $bindir/i2m"; tail -n 20 "$log"; fail=1
  fi
done
[ $fail = 0 ] && echo "check-builds: every installed toolchain passed" || echo "check-builds: FAILURES"
exit $fail
