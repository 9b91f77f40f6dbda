#!/bin/sh
# Shared-memory speedup: knee_atlas.nrrd at about 6 M tets on 1 and 2 threads (this
# machine's cores), best of two runs each, with speculation (the default) and in the
# deterministic mode; records wall times, speedups, rollbacks and per-thread figures into
# bench/results/threads.json.
set -eu
DATA=${I2M_DATA:-../shared/data}
OUT=bench/results
TMP=$(mktemp -d)
PY=${PYTHON:-/usr/bin/python3}
# alternate 1, 2, 1, 2 threads and keep each one's fastest run: this shared machine's speed
# drifts by +-20% from run to run
for mode in spec det; do
  flag=""
  [ "$mode" = det ] && flag="--deterministic"
  for round in 1 2; do
    for T in 1 2; do
      bin/i2m "$DATA/knee_atlas.nrrd" -o "$TMP/knee.vtu" --delta 0.33 --threads "$T" $flag --report "$TMP/run.json" --quiet
      rm -f "$TMP/knee.vtu"
      best="$TMP/$mode$T.json"
      if [ ! -f "$best" ] || "$PY" -c "import json,sys; a,b=(json.load(open(f))['time_seconds']['refinement'] for f in sys.argv[1:]); sys.exit(0 if a < b else 1)" "$TMP/run.json" "$best"; then
        cp "$TMP/run.json" "$best"
      fi
    done
  done
done
"$PY" - "$TMP" <<'PY' | tee "$OUT/threads.json"
import json, sys
tmp = sys.argv[1]
def mode(m):
    r1, r2 = (json.load(open(f"{tmp}/{m}{T}.json")) for T in (1, 2))
    t1, t2 = r1["time_seconds"]["refinement"], r2["time_seconds"]["refinement"]
    return {"tets": [r1["counts"]["tetrahedra"], r2["counts"]["tetrahedra"]],
            "checksums": [r1["counts"]["checksum"], r2["counts"]["checksum"]],
            "refinement_seconds": {"1": t1, "2": t2},
            "total_seconds": {"1": r1["time_seconds"]["total"], "2": r2["time_seconds"]["total"]},
            "speedup_refinement": t1 / t2, "speedup_total": r1["time_seconds"]["total"] / r2["time_seconds"]["total"],
            "tets_per_second": {"1": r1["speed"]["tets_per_second"], "2": r2["speed"]["tets_per_second"]},
            "rollbacks": r2["refinement"]["rollbacks"], "insertions": r2["refinement"]["insertions"],
            "per_thread": r2["threads"]["per_thread"], "binding": r2["threads"]["binding"],
            "bytes_per_tet": {"1": r1["memory"]["bytes_per_tet"], "2": r2["memory"]["bytes_per_tet"]}}
spec, det = mode("spec"), mode("det")
res = {"benchmark": "threads", "input": "knee_atlas.nrrd", "delta": 0.33, "target_speedup": 1.8}
res.update(spec)
res["deterministic"] = det
print(json.dumps(res, indent=1))
PY
rm -rf "$TMP"
