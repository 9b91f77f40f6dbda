#!/bin/sh
# The finite-element bounds on real images: `--sliver-angle 15` at 1 and 2 threads, every mesh
# through the independent checker with every guarantee of the refinement issue
# (guarantees.sh), each large tissue in one piece (--require-whole 10000) and every tet's
# dihedral angles within 15..160 degrees.  `make check` runs it on the spine and the vertebrae
# (test_slivers.sh covers the liver, the knee and the brain); `make check-full` on all seven
# images of ../shared/data (seven minutes more on 2 cores).
set -eu
. "$(dirname "$0")/guarantees.sh"
fail=0
for img in ${I2M_IMAGES:-spine_verse009.nii.gz vertebrae_vbseg.mha}; do
  for T in 1 2; do
    "$BIN/i2m" "$DATA/$img" -o "$TMP/s$T.vtu" --vtu-raw --threads "$T" --sliver-angle 15 --report "$TMP/s$T.json" \
      --quiet 2>"$TMP/s$T.err"
    if check_guarantees "$TMP/s$T.vtu" "$DATA/$img" "$TMP/s$T.json" --require-whole 10000 --min-dihedral 15 \
      --max-dihedral 160 >"$TMP/s$T.check" 2>&1; then
      "$PY" -c "
import json, sys
r = json.load(open(sys.argv[1])); q = r['quality']; t = r['time_seconds']
print('ok   %s, %s thread(s): %d tets, dihedral %.3f..%.3f deg, pass %.2f s = %.2f x the refinement' % (
    sys.argv[2], sys.argv[3], r['counts']['tetrahedra'], q['min_dihedral'], q['max_dihedral'], t['slivers'],
    t['slivers'] / t['refinement']))" "$TMP/s$T.json" "$img" "$T"
    else
      echo "FAIL $img, $T thread(s), --sliver-angle 15:"; grep VIOLATED "$TMP/s$T.check" || tail -3 "$TMP/s$T.check"
      fail=1
    fi
  done
done
exit $fail
