#!/bin/sh
# Shared-memory parallel refinement on real images: with 1, 2 and 4 worker threads (4 on
# this 2-core machine: oversubscribed, the hardest case for the locks), every mesh is valid
# and meets every guarantee (checked independently, see guarantees.sh; every image component
# of >= 10,000 voxels in one piece: the 2-thread run is the default one of this machine, and
# test_mesh_real_images.sh leaves these images to this test), the per-label volumes
# agree across thread counts within 1% (labels of >= 10000 voxels), and so do the 99th
# percentiles (mesh to image, image to mesh, two-sided) and the mean distances.
# `make check` runs three images; `make check-full` sets I2M_IMAGES to all seven.
set -eu
. "$(dirname "$0")/guarantees.sh"
fail=0
for img in ${I2M_IMAGES:-liver.inr.gz spine_verse009.nii.gz brain_kmeans_noisy.nii.gz}; do
  for T in 1 2 4; do
    "$BIN/i2m" "$DATA/$img" -o "$TMP/m$T.vtu" --vtu-raw --threads "$T" --report "$TMP/r$T.json" --quiet
    if ! check_guarantees "$TMP/m$T.vtu" "$DATA/$img" "$TMP/r$T.json" --require-whole 10000 --json >"$TMP/c$T.json"; then
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
worst = pworst = 0.0
for T in (2, 4):
    for l in c[T]["fidelity"]["labels"]:
        if l["label"] in base:
            d = abs(l["mesh_volume"] - base[l["label"]]["mesh_volume"]) / base[l["label"]]["mesh_volume"]
            worst = max(worst, d)
            if d > 0.01:
                ok = False
                print(f"FAIL {img}: label {l['label']} volume differs by {100*d:.2f}% between 1 and {T} threads")
    # the 99th percentiles (each direction and both pooled) and the mean distances
    for side in ("mesh_to_image", "image_to_mesh", "hausdorff"):
        for fig in ("p99_mm", "mean_mm"):
            x1, xT = c[1]["fidelity"][side][fig], c[T]["fidelity"][side][fig]
            d = abs(xT - x1) / x1
            pworst = max(pworst, d)
            if d > 0.01:
                ok = False
                print(f"FAIL {img}: {side} {fig} {x1:.4f} (1 thread) vs {xT:.4f} ({T} threads)")
# the single-point maxima are bounded (mesh to image by delta), not expected to agree: shown
maxima = ", ".join(f"{s} max {min(c[T]['fidelity'][s]['max_mm'] for T in c):.3f}-{max(c[T]['fidelity'][s]['max_mm'] for T in c):.3f} mm"
                   for s in ("mesh_to_image", "image_to_mesh"))
speed = ", ".join(f"{T} thr {r[T]['time_seconds']['refinement']:.2f} s ({r[T]['refinement']['rollbacks']} rollbacks)" for T in (1, 2, 4))
print(f"{'ok  ' if ok else 'FAIL'} {img}: valid and within bounds at 1, 2, 4 threads; volumes agree within {100*worst:.2f}%, p99s and means within {100*pworst:.2f}%; {maxima}; {speed}")
sys.exit(0 if ok else 1)
PY
done
exit $fail
