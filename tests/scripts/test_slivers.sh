#!/bin/sh
# --sliver-angle: the optional sliver perturbation after refinement.  On a real image, one
# thread (so the refinement before it is the same run to run), the independent checker finds
# every guarantee of the refinement issue still met and no tet left with a dihedral angle
# below 5 degrees (there are thousands without the pass; i2m-check --min-dihedral 5 fails the
# plain mesh and passes the perturbed one); the run's dihedral bands before and after the pass
# are the checker's on the two meshes.  At 15 degrees the liver and the brain come out within
# 15..160 degrees, and the knee keeps each large tissue in one piece.  Bad values of the option
# get one error line.
set -eu
. "$(dirname "$0")/guarantees.sh"
IMG=$DATA/liver.inr.gz
"$BIN/i2m" "$IMG" -o "$TMP/plain.vtu" --delta 1.0 --threads 1 --quiet
"$BIN/i2m" "$IMG" -o "$TMP/perturbed.vtu" --delta 1.0 --threads 1 --sliver-angle 5 --report "$TMP/perturbed.json" --quiet
check_guarantees "$TMP/perturbed.vtu" "$IMG" "$TMP/perturbed.json" --min-dihedral 5 >/dev/null
if "$BIN/i2m-check" "$TMP/plain.vtu" --min-dihedral 5 >/dev/null; then
  echo "FAIL: i2m-check --min-dihedral 5 passed a mesh with slivers"; exit 1
fi
"$BIN/i2m-check" "$TMP/plain.vtu" --json >"$TMP/plain.check.json"
"$BIN/i2m-check" "$TMP/perturbed.vtu" --json >"$TMP/perturbed.check.json"
"$PY" - "$TMP/plain.check.json" "$TMP/perturbed.check.json" "$TMP/perturbed.json" <<'PY'
import json, sys
a = json.load(open(sys.argv[1]))["quality"]; b = json.load(open(sys.argv[2]))["quality"]
run = json.load(open(sys.argv[3])); rep = run["slivers"]
# the run's dihedral bands, before the pass and after it, are the checker's on the plain mesh
# (the same refinement: one thread) and on the perturbed one (two independent computations)
bands = ["below_5", "below_10", "below_15", "below_20", "above_160", "above_170"]
for mine, theirs, what in ((rep["dihedral_bands_before"], a, "before"), (run["quality"]["dihedral_bands"], b, "after")):
    got = [mine[k] for k in bands]; want = [theirs["tets_dihedral_" + k] for k in bands]
    if got != want:
        sys.exit("dihedral bands %s the pass: the run says %s, i2m-check %s" % (what, got, want))
print("below 5 deg: %d -> %d; smallest dihedral %.3f -> %.3f deg (the run's report: %d -> %d, %d of %d moves kept)" % (
    a["tets_dihedral_below_5"], b["tets_dihedral_below_5"], a["min_dihedral"], b["min_dihedral"],
    rep["before"], rep["after"], rep["moves_kept"], rep["moves_tried"]))
ok = (a["tets_dihedral_below_5"] > 1000 and b["tets_dihedral_below_5"] == 0 and rep["after"] == 0
      and b["min_dihedral"] >= 5.0)
sys.exit(0 if ok else 1)
PY
# 15 degrees: the liver at delta 1 comes out with every tet within 15..160 degrees (the stages
# that lift the smallest angle, with points inserted at slivers' circumcentres, then the one
# for the wide angles), every guarantee still met
"$BIN/i2m" "$IMG" -o "$TMP/fe.vtu" --delta 1.0 --threads 1 --sliver-angle 15 --report "$TMP/fe.json" --quiet
check_guarantees "$TMP/fe.vtu" "$IMG" "$TMP/fe.json" --min-dihedral 15 --max-dihedral 160 >/dev/null ||
  { echo "FAIL: --sliver-angle 15 left a tet outside 15..160 degrees (or broke a guarantee)"; exit 1; }
"$PY" - "$TMP/fe.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))["slivers"]
print("15 deg: %d -> %d tets below it, %d points inserted, %d of %d changes kept" % (
    s["before"], s["after"], s["points_inserted"], s["moves_kept"], s["moves_tried"]))
sys.exit(0 if s["before"] > 10000 and s["after"] == 0 and s["points_inserted"] > 0 else 1)
PY
# the hardest image tried, a noisy k-means segmentation of a brain, default options: every tet
# within 15..160 degrees too (before the picking region's points, one thread left 6 tets below
# 15 degrees and 1 above 160)
BRAIN=$DATA/brain_kmeans_noisy.nii.gz
"$BIN/i2m" "$BRAIN" -o "$TMP/brain.vtu" --threads 1 --sliver-angle 15 --report "$TMP/brain.json" --quiet
check_guarantees "$TMP/brain.vtu" "$BRAIN" "$TMP/brain.json" --min-dihedral 15 --max-dihedral 160 >/dev/null ||
  { echo "FAIL: --sliver-angle 15 left a tet of the brain outside 15..160 degrees (or broke a guarantee)"; exit 1; }
# the pass keeps each tissue in one piece: on the knee at delta 0.8 (one thread) its changes
# cut the thin labels 41 and 46 into 2 and 3 pieces after the component rule had joined them,
# until a change that would cut a tissue's path through its region was refused (regions.c)
KNEE=$DATA/knee_atlas.nrrd
"$BIN/i2m" "$KNEE" -o "$TMP/knee.vtu" --delta 0.8 --threads 1 --sliver-angle 15 --quiet 2>"$TMP/knee.err"
"$BIN/i2m-check" "$TMP/knee.vtu" --image "$KNEE" --no-distances --require-whole 10000 --min-dihedral 15 \
  --max-dihedral 160 >"$TMP/knee.check" ||
  { echo "FAIL: --sliver-angle 15 split a tissue of the knee (or left a tet outside 15..160 degrees)"; grep VIOLATED "$TMP/knee.check"; exit 1; }
for bad in -1 31 x; do
  if "$BIN/i2m" "$IMG" -o "$TMP/bad.vtu" --sliver-angle "$bad" >"$TMP/out" 2>"$TMP/err"; then
    echo "FAIL: --sliver-angle $bad was accepted"; exit 1
  fi
  [ "$(wc -l <"$TMP/err")" -eq 1 ] || { echo "FAIL: --sliver-angle $bad: not one error line"; cat "$TMP/err"; exit 1; }
done
echo "ok: sliver perturbation"
