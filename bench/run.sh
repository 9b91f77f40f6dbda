#!/bin/sh
# make bench: runs every benchmark and writes its figures to bench/results/*.json.
set -eu
bdir=$1
cd "$(dirname "$0")/.."
mkdir -p bench/results
echo "== Delaunay kernel, one thread (10^6 and 10^7 random points in the unit cube)"
"$bdir/bench_delaunay" 1000000 10000000 --json bench/results/delaunay.json
echo "== predicates"
[ -x "$bdir/bench_predicates" ] && "$bdir/bench_predicates" | tail -n 12 || true
for s in bench/bench_*.sh; do
  [ -f "$s" ] || continue
  [ "$s" = bench/bench_mpi.sh ] && continue # (make bench-mpi: the ranks x threads sweep: minutes)
  echo "== $(basename "$s")"
  sh "$s"
done
echo "figures written to bench/results/ (make bench-mpi: the MPI sweep over ranks x threads)"
ls bench/results
