#!/bin/sh
# The deterministic mode (--deterministic): with 1, 2 and 4 worker threads (4 on this 2-core
# machine: oversubscribed), the written mesh files are byte for byte the same, the reports
# give the same order-independent checksum of the whole triangulation, and the mesh meets
# every guarantee (checked independently, see guarantees.sh); with the sliver perturbation
# (--sliver-angle 5) the files of 1 and 4 threads are the same too.  `make check` runs one image;
# I2M_IMAGES names others (`make check-full` runs all seven).
set -eu
. "$(dirname "$0")/guarantees.sh"
fail=0
for img in ${I2M_IMAGES:-spine_verse009.nii.gz}; do
  for T in 1 2 4; do
    "$BIN/i2m" "$DATA/$img" -o "$TMP/d$T.vtu" --threads "$T" --deterministic --report "$TMP/d$T.json" --quiet
  done
  sums=$("$PY" -c "import json,sys; print(' '.join(json.load(open(f))['counts']['checksum'] for f in sys.argv[1:]))" \
    "$TMP/d1.json" "$TMP/d2.json" "$TMP/d4.json")
  set -- $sums
  if [ "$1" != "$2" ] || [ "$1" != "$3" ]; then
    echo "FAIL $img: checksums differ across 1, 2, 4 threads: $sums"; fail=1
  fi
  for T in 2 4; do
    if ! cmp -s "$TMP/d1.vtu" "$TMP/d$T.vtu"; then
      echo "FAIL $img: the mesh written with $T threads differs from the one written with 1"; fail=1
    fi
  done
  if check_guarantees "$TMP/d1.vtu" "$DATA/$img" "$TMP/d1.json" >"$TMP/check.txt" 2>&1; then
    echo "ok   $img: the same file on 1, 2, 4 threads (checksum $1), every guarantee met; $("$PY" -c "
import json, sys
r = {T: json.load(open(sys.argv[1] + '/d%d.json' % T)) for T in (1, 2, 4)}
t = r[1]['threads']
print('tiles of %.3g mm, %d rounds, %d elements left to the sequential passes; refinement %s s' % (
    t['tile_mm'], t['rounds'], t['sequential_ops'], ', '.join('%.2f' % r[T]['time_seconds']['refinement'] for T in (1, 2, 4))))
" "$TMP")"
  else
    echo "FAIL $img:"; grep -E "VIOLATED|INVALID|validity|two-sided|mesh->image" "$TMP/check.txt"; fail=1
  fi
  for T in 1 4; do
    "$BIN/i2m" "$DATA/$img" -o "$TMP/s$T.vtu" --threads "$T" --deterministic --sliver-angle 5 --quiet
  done
  if cmp -s "$TMP/s1.vtu" "$TMP/s4.vtu"; then
    echo "ok   $img: with --sliver-angle 5, the same file on 1 and 4 threads"
  else
    echo "FAIL $img: with --sliver-angle 5, the meshes of 1 and 4 threads differ"; fail=1
  fi
  rm -f "$TMP"/d*.vtu "$TMP"/s*.vtu
done
exit $fail
