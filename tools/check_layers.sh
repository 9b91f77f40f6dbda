#!/bin/sh
# Fails when a layer includes a header of a layer below it (STYLE.md section 1).
set -u
rank() {
  case "$1" in
    base) echo 0;; geom) echo 1;; image) echo 2;; delaunay) echo 3;; refine) echo 4;;
    threads) echo 5;; dist) echo 6;; io) echo 7;; api) echo 8;; cli) echo 9;; *) echo -1;;
  esac
}
# header -> layer that owns it
hlayer() {
  case "$1" in
    base.h) echo base;; predicates.h|geometry.h) echo geom;; image.h|edt.h) echo image;;
    dt.h) echo delaunay;; tetmesh.h|refine.h|quality.h) echo refine;; threads.h) echo threads;;
    dist.h) echo dist;; io.h|report.h) echo io;; pipeline.h) echo api;; *) echo unknown;;
  esac
}
bad=0
for f in src/*/*.c src/*/*.h; do
  [ -f "$f" ] || continue
  layer=$(echo "$f" | cut -d/ -f2)
  lr=$(rank "$layer")
  for h in $(grep -ho '#include "i2m/[a-z_]*\.h"' "$f" | sed 's/.*i2m\/\(.*\)"/\1/'); do
    hl=$(hlayer "$h")
    [ "$hl" = unknown ] && { echo "check-layers: $f includes i2m/$h, which no layer owns" >&2; bad=1; continue; }
    if [ "$(rank "$hl")" -gt "$lr" ]; then
      echo "check-layers: $f (layer $layer) includes i2m/$h of layer $hl above it" >&2; bad=1
    fi
  done
  case "$layer" in base|geom|image|delaunay|refine)
    if grep -q '#include <mpi.h>\|#include <omp.h>' "$f"; then
      echo "check-layers: $f (layer $layer) uses MPI or OpenMP directly" >&2; bad=1
    fi;;
  esac
done
[ $bad = 0 ] && echo "check-layers: ok"
exit $bad
