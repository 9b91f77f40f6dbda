#!/bin/sh
# Shared-memory parallel refinement on real images: with 1, 2 and 4 worker threads (4 on
# this 2-core machine: oversubscribed, the hardest case for the locks), every mesh is valid
# and meets every guarantee (checked independently, see guarantees.sh), the per-label volumes
# agree across thread counts within 1% (labels of >= 10000 voxels) and the two-sided 99th
# percentile within 1% or 0.04 voxel (the spread between equally valid meshes, see below).
# `make check` runs three images; `make check-full` sets I2M_IMAGES to all seven.
set -eu
. "$(dirname "$0")/guarantees.sh"
fail=0
for img in ${I2M_IMAGES:-liver.inr.gz spine_verse009.nii.gz brain_kmeans_noisy.nii.gz}; do
  for T in 1 2 4; do
    "$BIN/i2m" "$DATA/$img" -o "$TMP/m$T.vtu" --threads "$T" --report "$TMP/r$T.json" --quiet
    if ! check_guarantees "$TMP/m$T.vtu" "$DATA/$img" "$TMP/r$T.json" --json >"$TMP/c$T.json"; then
      echo "FAIL $img, $T threads:"; "$PY" -c "import json,sys; d=json.load(open(sys.argv[1])); print(d['violations'], d['validity']['errors'])" "$TMP/c$T.json"
      fail=1
    fi
  done
  "$PY" - "$TMP" "$img" <<'PY' || fail=1
import json, sys
tmp, img = sys.argv[1], sys.argv[2]
c = {T: json.load(open(f"{tmp}/c{T}.json")) for T in (1, 2, 4)}
r = {T: json.load(open(f"{tmp}/r{T}.json")) for T in (1, 2, 4)}
ok = True
base = {l["label"]: l for l in c[1]["fidelity"]["labels"] if l["voxels"] >= 10000}
worst = 0.0
for T in (2, 4):
    for l in c[T]["fidelity"]["labels"]:
        if l["label"] in base:
            d = abs(l["mesh_volume"] - base[l["label"]]["mesh_volume"]) / base[l["label"]]["mesh_volume"]
            worst = max(worst, d)
            if d > 0.01:
                ok = False
                print(f"FAIL {img}: label {l['label']} volume differs by {100*d:.2f}% between 1 and {T} threads")
    p1, pT = c[1]["fidelity"]["hausdorff"]["p99_mm"], c[T]["fidelity"]["hausdorff"]["p99_mm"]
    vox = c[1]["fidelity"]["min_spacing"]
    # the p99 of one image differs between equally valid meshes by more than 1%: on knee_atlas,
    # one thread with only the order of R7's removals changed gives 0.1896-0.1969 mm (a spread
    # of 0.026 voxel); thread counts must agree within that noise, with a margin
    if abs(pT - p1) > max(0.01 * p1, 0.04 * vox):
        ok = False
        print(f"FAIL {img}: two-sided p99 {p1:.4f} mm (1 thread) vs {pT:.4f} mm ({T} threads)")
speed = ", ".join(f"{T} thr {r[T]['time_seconds']['refinement']:.2f} s ({r[T]['refinement']['rollbacks']} rollbacks)" for T in (1, 2, 4))
print(f"{'ok  ' if ok else 'FAIL'} {img}: valid and within bounds at 1, 2, 4 threads; volumes agree within {100*worst:.2f}%; {speed}")
sys.exit(0 if ok else 1)
PY
done
exit $fail
