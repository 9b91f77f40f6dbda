#!/bin/sh
# make bench-large: i2m at scale on one machine (minutes; not part of make bench).
#  1. the knee atlas upsampled 2x per axis by i2m-mkimage (1024 x 1024 x 238 = 250 M voxels)
#     meshed at default options;
#  2. the knee atlas at --delta 0.073 (about 153 M tets).
# Each on all cores; prints tets, time, peak memory and bytes per tet (the report's figures),
# checks the 150 M-tet run's peak against 20 GiB, and writes bench/results/large_<date>.json.
# The meshes go to a scratch directory under build/ (about 8 GB for the second), removed after.
#   bench/large.sh [THREADS]      (I2M_LARGE_DELTA overrides 0.073)
set -eu
cd "$(dirname "$0")/.."
T=${1:-$(getconf _NPROCESSORS_ONLN 2>/dev/null || echo 2)}
DATA=${I2M_DATA:-../shared/data}
DELTA=${I2M_LARGE_DELTA:-0.073}
PY=${PYTHON:-/usr/bin/python3}
W=build/large
rm -rf "$W"
mkdir -p "$W" bench/results
trap 'rm -rf "$W"' EXIT
out=bench/results/large_$(date +%Y%m%d-%H%M%S).json

echo "bench-large: upsampling the knee atlas 2x per axis"
bin/i2m-mkimage --from "$DATA/knee_atlas.nrrd" --upsample 2 --gzip -o "$W/knee2.nrrd"
bin/i2m-info "$W/knee2.nrrd" | sed -n 4,5p

run() { # NAME IMAGE OPTIONS...
  name=$1 img=$2
  shift 2
  echo "bench-large: $name: i2m $img $* --threads $T"
  bin/i2m "$img" -o "$W/$name.vtu" --threads "$T" --report "$W/$name.json" "$@" | grep -E "^  (mesh|time|memory|speed)"
  ls -l "$W/$name.vtu" | awk '{printf "  file         %.2f GB\n", $5 / 1e9}'
  rm -f "$W/$name.vtu"
}
run upsampled "$W/knee2.nrrd"
run delta "$DATA/knee_atlas.nrrd" --delta "$DELTA"

"$PY" - "$W/upsampled.json" "$W/delta.json" "$out" "$T" <<'EOF'
import json, sys
runs = {}
for name, path in (("upsampled_knee_250M_voxels", sys.argv[1]), ("knee_delta", sys.argv[2])):
    j = json.load(open(path))
    runs[name] = {"tets": j["counts"]["tetrahedra"], "seconds": j["time_seconds"]["total"],
                  "refinement_seconds": j["time_seconds"]["refinement"],
                  "peak_rss_bytes": j["memory"]["peak_rss_bytes"], "bytes_per_tet": j["memory"]["bytes_per_tet"],
                  "delta": j["parameters"]["delta"], "threads": int(sys.argv[4])}
json.dump(runs, open(sys.argv[3], "w"), indent=1)
d = runs["knee_delta"]
gib = d["peak_rss_bytes"] / 2**30
print("bench-large: %.1f M tets in %.0f s, peak %.2f GiB (%.0f bytes per tet): %s" % (
    d["tets"] / 1e6, d["seconds"], gib, d["bytes_per_tet"],
    "within 20 GiB" if gib <= 20 and d["tets"] >= 150e6 else "NOT within the target (150 M tets, 20 GiB)"))
print("written to " + sys.argv[3])
EOF
