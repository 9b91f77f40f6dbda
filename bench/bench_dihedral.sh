#!/bin/sh
# Dihedral-angle benchmark: liver.inr.gz and knee_atlas.nrrd at about 1 M and 6 M output tets
# on one thread, each meshed once with the sliver pass aimed at the finite-element goal
# (--sliver-angle 15, or $I2M_BENCH_SLIVER): the tets per dihedral band before the pass (the
# default mesh: the same refinement) and after it, the smallest and largest angles after it,
# and the pass's time as a fraction of the refinement's (the goal: at most 0.5).  Prints the
# table and writes bench/results/dihedral.json.
set -eu
DATA=${I2M_DATA:-../shared/data}
OUT=bench/results
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
PY=${PYTHON:-/usr/bin/python3}
ANGLE=${I2M_BENCH_SLIVER:-15}
THREADS=${I2M_BENCH_THREADS:-1}
mkdir -p "$OUT"
runs=""
for spec in "liver.inr.gz 0.667 1M" "liver.inr.gz 0.29 6M" "knee_atlas.nrrd 0.8 1M" "knee_atlas.nrrd 0.33 6M"; do
  set -- $spec
  name="${1%%.*}_$3"
  bin/i2m "$DATA/$1" -o "$TMP/$name.vtu" --vtu-raw --delta "$2" --threads "$THREADS" --sliver-angle "$ANGLE" \
    --report "$TMP/$name.json" --quiet 2>/dev/null
  runs="$runs $TMP/$name.json"
  rm -f "$TMP/$name.vtu"
done
"$PY" - "$ANGLE" "$THREADS" "$OUT/dihedral.json" $runs <<'PY'
import json, sys
angle, threads, out, files = float(sys.argv[1]), int(sys.argv[2]), sys.argv[3], sys.argv[4:]
keys = ["below_5", "below_10", "below_15", "below_20", "above_160", "above_170"]
rows = []
print("dihedral angles, %d thread(s), pass --sliver-angle %g (tets per band: smallest below 5/10/15/20 deg, largest above 160/170 deg)" % (threads, angle))
print("%-10s %9s  %-34s %-34s %15s %8s %8s %6s" % ("mesh", "tets", "bands before the pass", "bands after", "angles after", "refine", "pass", "ratio"))
for f in files:
    r = json.load(open(f))
    name = f.split("/")[-1][:-5]
    q, s, t = r["quality"], r["slivers"], r["time_seconds"]
    before = [s["dihedral_bands_before"][k] for k in keys]
    after = [q["dihedral_bands"][k] for k in keys]
    ratio = t["slivers"] / t["refinement"] if t["refinement"] > 0 else float("nan")
    rows.append({"mesh": name, "input": r["input"].split("/")[-1], "delta": r["parameters"]["delta"],
                 "tets": r["counts"]["tetrahedra"], "sliver_angle": angle, "threads": threads,
                 "bands_before": dict(zip(keys, before)), "bands_after": dict(zip(keys, after)),
                 "min_dihedral_before": s["min_dihedral_before"], "min_dihedral": q["min_dihedral"],
                 "max_dihedral": q["max_dihedral"], "refinement_seconds": t["refinement"],
                 "pass_seconds": t["slivers"], "pass_over_refinement": ratio})
    print("%-10s %9d  %-34s %-34s %6.2f..%6.2f %7.2fs %7.2fs %6.2f" % (
        name, r["counts"]["tetrahedra"], "/".join(map(str, before)), "/".join(map(str, after)),
        q["min_dihedral"], q["max_dihedral"], t["refinement"], t["slivers"], ratio))
json.dump({"benchmark": "dihedral", "goal": {"min_dihedral": 15, "max_dihedral": 160, "pass_over_refinement": 0.5},
           "runs": rows}, open(out, "w"), indent=1)
print("figures written to %s" % out)
PY
