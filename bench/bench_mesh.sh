#!/bin/sh
# Meshing benchmark: liver.inr.gz and knee_atlas.nrrd at about 1 M and 6 M output tets on
# one thread; records tets/s, time per phase, peak memory and bytes per tet from each run's
# report into bench/results/mesh_1thread.json.  (delta chosen for the size; see README.)
set -eu
DATA=${I2M_DATA:-../shared/data}
OUT=bench/results
TMP=$(mktemp -d)
PY=${PYTHON:-/usr/bin/python3}
THREADS=${I2M_BENCH_THREADS:-1}
runs=""
for spec in "liver.inr.gz 0.667 1M" "liver.inr.gz 0.29 6M" "knee_atlas.nrrd 0.8 1M" "knee_atlas.nrrd 0.33 6M"; do
  set -- $spec
  name="${1%%.*}_$3"
  bin/i2m "$DATA/$1" -o "$TMP/$name.vtu" --delta "$2" --threads "$THREADS" --report "$TMP/$name.json" --quiet
  "$PY" - "$TMP/$name.json" "$name" <<'PY'
import json, sys
r = json.load(open(sys.argv[1])); t = r["time_seconds"]
print("%-14s delta %-5g %9d tets  refine %6.2f s  total %6.2f s  %8.0f tets/s (refinement)  %7.0f tets/s (total)  %4.0f bytes/tet  peak %5.0f MB" % (
    sys.argv[2], r["parameters"]["delta"], r["counts"]["tetrahedra"], t["refinement"], t["total"],
    r["speed"]["tets_per_second"], r["speed"]["tets_per_second_total"], r["memory"]["bytes_per_tet"],
    r["memory"]["peak_rss_bytes"] / 2**20))
PY
  runs="$runs $TMP/$name.json"
  rm -f "$TMP/$name.vtu"
done
"$PY" - $runs >"$OUT/mesh_${THREADS}thread.json" <<'PY'
import json, sys
out = []
for f in sys.argv[1:]:
    r = json.load(open(f))
    out.append({"input": r["input"].split("/")[-1], "delta": r["parameters"]["delta"], "tets": r["counts"]["tetrahedra"],
                "threads": r["parameters"]["threads"], "time_seconds": r["time_seconds"], "speed": r["speed"],
                "memory": r["memory"], "quality": {k: r["quality"][k] for k in ("min_dihedral", "max_dihedral", "max_radius_edge")}})
json.dump({"benchmark": "meshing", "runs": out,
           "targets": {"tets_per_second": 500000, "bytes_per_tet": 200}}, sys.stdout, indent=1)
PY
echo "figures written to $OUT/mesh_${THREADS}thread.json"
rm -rf "$TMP"
