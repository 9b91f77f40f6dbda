#!/bin/sh
# Every real image in $I2M_DATA meshes with default options, and the independent checker
# confirms on the written file: a valid mesh; radius-edge <= the bound for every tet;
# interface planar angles >= 30 deg (at most 0.1% exceptions); every mesh interface point
# within delta of the image's interfaces; the 99th percentile of the two-sided distance
# <= delta/2; every label of >= 100 voxels present; per-label volume within 5% for labels
# of >= 10000 voxels.  Formats are rotated so that all three writers are exercised.
set -eu
BIN=${I2M_BIN:-bin}
DATA=${I2M_DATA:-../shared/data}
TMP=${I2M_TMP:-$(mktemp -d)}
PY=${PYTHON:-/usr/bin/python3}
fail=0
n=0
for img in liver.inr.gz knee_atlas.nrrd abdominal_atlas.nrrd head_colin27.nii.gz spine_verse009.nii.gz \
           vertebrae_vbseg.mha brain_kmeans_noisy.nii.gz; do
  [ -f "$DATA/$img" ] || { echo "missing $DATA/$img"; fail=1; continue; }
  case $n in 0) ext=vtu;; 1) ext=mesh;; *) ext=msh;; esac
  n=$(( (n + 1) % 3 ))
  out="$TMP/${img%%.*}.$ext"
  rep="$TMP/${img%%.*}.json"
  start=$(date +%s)
  if ! timeout 900 "$BIN/i2m" "$DATA/$img" -o "$out" --report "$rep" --quiet; then
    echo "FAIL $img: i2m failed"; fail=1; continue
  fi
  delta=$("$PY" -c "import json,sys; print(json.load(open(sys.argv[1]))['parameters']['delta'])" "$rep")
  ratio=$("$PY" -c "import json,sys; print(json.load(open(sys.argv[1]))['parameters']['ratio'])" "$rep")
  half=$("$PY" -c "print($delta / 2)")
  if "$BIN/i2m-check" "$out" --image "$DATA/$img" --max-ratio "$ratio" --min-facet-angle 30 \
       --facet-angle-exceptions 0.001 --max-mesh-to-image "$delta" --max-p99 "$half" \
       --max-volume-error 5 --require-labels 100 >"$TMP/check.txt" 2>&1; then
    echo "ok   $img ($ext, delta $delta mm, $(( $(date +%s) - start )) s): $(grep -E '^mesh ' "$TMP/check.txt" | cut -d: -f2)"
  else
    echo "FAIL $img:"; grep -E "VIOLATED|INVALID|validity|two-sided|mesh->image" "$TMP/check.txt"; fail=1
  fi
  rm -f "$out"
done
exit $fail
