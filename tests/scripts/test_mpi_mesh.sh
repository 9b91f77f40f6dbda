#!/bin/sh
# The distributed level, end to end.  A synthetic image (96^3 voxels, 64 subregions: --depth 2)
# and two real images (the spine at --delta 1.2, the vertebrae at their default: the octree's
# cells stay 16 delta wide, narrower ones make the background bound cost many insertions), each
# meshed at 1, 2 and 4 ranks (oversubscribed) x 1 and 2 threads under mpirun, each run under a
# timeout.  Every mesh (stitched by rank 0, or written as .pvtu pieces) must meet every
# guarantee of the one-process mesh (guarantees.sh, and every image component of >= 10,000
# voxels in one piece), and its element count, per-label volumes (labels of >= 1,000 voxels)
# must lie within 1% of the one-process run's, and its 99th-percentile interface distance no
# more than 1% above it (a closer mesh passes), with the same subregions (--deterministic on one process: the same coarse mesh, octree and background
# bound; the default one-process run, which needs no subregions, is shown beside it).  The run
# must really be distributed: every rank ran tasks and inserted points, the ranks' insertions
# add up to within 10% of the one process's, some rank answered a request for submeshes
# while its threads refined, and some task went without the cells beyond faces of its
# subregion that its elements did not need.  The knee atlas at 2 ranks (depth 3): no rank ever held more than
# 75% of the final tets.  --sliver-angle under MPI keeps every guarantee and treats the
# slivers.  --deterministic: the same checksum on one process and at 1, 2 and 4 ranks x 1 and
# 2 threads, every rank making at least a tenth of the insertions.
set -eu
. "$(dirname "$0")/guarantees.sh"
if ! command -v mpirun >/dev/null 2>&1; then
  echo "SKIP: no mpirun"
  exit 0
fi
export OMPI_MCA_mpi_yield_when_idle=1 OMPI_MCA_rmaps_base_oversubscribe=1
MPIRUN="mpirun --oversubscribe --bind-to none"
[ "$(id -u)" = 0 ] && MPIRUN="$MPIRUN --allow-run-as-root"
mpirun --version 2>/dev/null | grep -qi "open mpi" || MPIRUN="mpirun" # (MPICH: no such flags)
fail=0
"$BIN/i2m-mkimage" --shape shells --dims 96,96,96 -o "$TMP/shells.nrrd"


# compare REF.json RUN.json REPORT_REF.json REPORT_RUN.json RANKS [peak] SPEC_REPORT.json: the 1%
# and the distributed checks (checker's JSON for the meshes, i2m's reports for the runs)
compare() {
  "$PY" - "$@" <<'EOF'
import json, sys
ref, run, rref, rrun, ranks = json.load(open(sys.argv[1])), json.load(open(sys.argv[2])), \
    json.load(open(sys.argv[3])), json.load(open(sys.argv[4])), int(sys.argv[5])
bad = []
def within(what, a, b, tol):
    if abs(a - b) > tol * abs(b): bad.append("%s %.6g vs %.6g one process (more than %g%%)" % (what, a, b, 100 * tol))
within("tets", run["mesh"]["tetrahedra"], ref["mesh"]["tetrahedra"], 0.01)
# the 99th-percentile distance may not be more than 1% worse (larger); a closer mesh passes: it
# varies by about +-1% between meshes made the same way (shells: 0.3189-0.3225 mm over eight
# runs at 1-4 ranks and one process), so a reference at the top of that range failed ranks
# whose meshes followed the image more closely
p99, p99_ref = run["fidelity"]["hausdorff"]["p99_mm"], ref["fidelity"]["hausdorff"]["p99_mm"]
if p99 > 1.01 * p99_ref: bad.append("p99 distance %.6g vs %.6g one process (more than 1%% worse)" % (p99, p99_ref))
rl = {l["label"]: l for l in ref["fidelity"]["labels"]}
for l in run["fidelity"]["labels"]:
    if l["voxels"] >= 1000 and l["label"] in rl:
        within("label %d volume" % l["label"], l["mesh_volume"], rl[l["label"]]["mesh_volume"], 0.01)
d = rrun["dist"]
ranks_seen = d["per_rank"]
if len(ranks_seen) != ranks: bad.append("%d ranks in the report" % len(ranks_seen))
for g in ranks_seen:
    if g["tasks"] <= 0 or g["insertions"] <= 0:
        bad.append("rank %d ran %d tasks, %d insertions" % (g["rank"], g["tasks"], g["insertions"]))
    # where the communication time went: a rank that joined submeshes spent time joining them,
    # one that packed some spent time packing, and the parts inside comm do not exceed it
    c = g["comm_parts_seconds"]
    if (g["submeshes_in"] > 0 and c["unpack"] <= 0) or (g["submeshes_out"] > 0 and c["pack"] <= 0):
        bad.append("rank %d: submeshes in %d, out %d, but joining %.4f s, packing %.4f s" % (
            g["rank"], g["submeshes_in"], g["submeshes_out"], c["unpack"], c["pack"]))
    if c["wait_data"] + c["unpack"] + c["merge"] > g["comm_seconds"] + 1e-3:
        bad.append("rank %d: its communication parts exceed its communication time" % g["rank"])
ins = sum(g["insertions"] for g in ranks_seen)
within("insertions", ins, rref["refinement"]["insertions"], 0.10)
if ranks > 1 and sum(g["answered_while_refining"] for g in ranks_seen) == 0:
    bad.append("no rank answered a request while its threads refined")
# tasks whose elements lie away from some faces of their subregion go without the cells there
# (tens a rank on these images; none would mean the feedback's sides were lost on the way)
skipping = sum(g["skipping_tasks"] for g in ranks_seen)
if ranks > 1 and skipping == 0:
    bad.append("no task went without some sides of its block")
final = sum(g["tets"] for g in ranks_seen)
peak = max(g["peak_tets"] for g in ranks_seen)
print("   tets %d, p99 %.4f mm, insertions %d (one process %d), peak held %.0f%% of %d, answered while refining %d, on part of their block %d, bytes/tet %.0f" % (
    run["mesh"]["tetrahedra"], run["fidelity"]["hausdorff"]["p99_mm"], ins, rref["refinement"]["insertions"],
    100.0 * peak / final, final, sum(g["answered_while_refining"] for g in ranks_seen), skipping, d["bytes_per_tet"]))
spec = json.load(open(sys.argv[7]))["refinement"]["insertions"]
print("   (the default one-process run: %d insertions, %+.1f%%)" % (spec, 100.0 * (ins - spec) / spec))
if sys.argv[6] == "peak" and ranks == 2 and peak > 0.75 * final:
    bad.append("a rank held %d tets at once, more than 75%% of the final %d" % (peak, final))
for b in bad: print("   " + b)
sys.exit(1 if bad else 0)
EOF
}

checksum() { "$PY" -c "import json,sys; print(json.load(open(sys.argv[1]))['counts']['checksum'])" "$1"; }
# every rank of a deterministic run made at least a tenth of the insertions (its phases' tasks
# go where their data is, but no rank may take them all)
spread() {
  "$PY" - "$1" <<'EOF2'
import json, sys
ranks = json.load(open(sys.argv[1]))["dist"]["per_rank"]
ins = [g["insertions"] for g in ranks]
ok = len(ins) == 1 or min(ins) >= 0.1 * sum(ins)
print("%s insertions per rank %s" % ("ok" if ok else "too few on a rank:", ins))
EOF2
}

# one image: $1 path, $2 i2m options, $3 "peak" to assert the 75% bound
run_image() {
  img=$1 opts=$2 name=$(basename "$1")
  # shellcheck disable=SC2086 # (opts: words)
  if ! timeout 300 "$BIN/i2m" "$img" -o "$TMP/ref.vtu" --vtu-raw --deterministic --threads 2 $opts --quiet --report "$TMP/ref_rep.json" ||
    ! timeout 300 "$BIN/i2m" "$img" -o "$TMP/spec.vtu" --vtu-raw --threads 2 $opts --quiet --report "$TMP/spec_rep.json"; then
    echo "FAIL $name: the one-process run failed"; fail=1; return
  fi
  "$BIN/i2m-check" "$TMP/ref.vtu" --image "$img" --json >"$TMP/ref.json" || true
  for np in 1 2 4; do
    for t in 1 2; do
      out="$TMP/m.vtu"
      [ $((np * t % 4)) = 0 ] && out="$TMP/m.pvtu" # (some runs write pieces)
      rm -f "$TMP"/m*.vtu "$TMP"/m.pvtu
      # shellcheck disable=SC2086
      if ! timeout 300 $MPIRUN -np $np "$BIN/i2m" "$img" -o "$out" --vtu-raw --threads $t $opts --quiet --report "$TMP/rep.json" \
        >"$TMP/log" 2>&1; then
        echo "FAIL $name, $np ranks x $t threads: i2m failed or timed out"; tail -5 "$TMP/log"; fail=1; continue
      fi
      if ! check_guarantees "$out" "$img" "$TMP/rep.json" --require-whole 10000 --json >"$TMP/run.json" 2>"$TMP/check.err"; then
        echo "FAIL $name, $np ranks x $t threads: a guarantee is broken"
        "$PY" -c "import json,sys; print(json.load(open(sys.argv[1])).get('violations'))" "$TMP/run.json" 2>/dev/null || cat "$TMP/check.err"
        fail=1; continue
      fi
      if compare "$TMP/ref.json" "$TMP/run.json" "$TMP/ref_rep.json" "$TMP/rep.json" $np "${3:-none}" "$TMP/spec_rep.json" >"$TMP/cmp.txt"; then
        echo "ok   $name, $np ranks x $t threads ($(basename "$out")): every guarantee, within 1% of one process"
        cat "$TMP/cmp.txt"
      else
        echo "FAIL $name, $np ranks x $t threads:"; cat "$TMP/cmp.txt"; fail=1
      fi
    done
  done
}

run_image "$TMP/shells.nrrd" "--depth 2" none
run_image "$DATA/spine_verse009.nii.gz" "--delta 1.2" none
run_image "$DATA/vertebrae_vbseg.mha" "" none

# the memory spread: the knee atlas (depth 3: a task's block is 27 of 512 subregions) at 2 ranks,
# where no rank may ever hold more than 75% of the final tets, and the pieces come out balanced
if timeout 300 $MPIRUN -np 2 "$BIN/i2m" "$DATA/knee_atlas.nrrd" -o "$TMP/k.pvtu" --vtu-raw --threads 1 --quiet --report "$TMP/k.json" \
  >"$TMP/log" 2>&1 && check_guarantees "$TMP/k.pvtu" "$DATA/knee_atlas.nrrd" "$TMP/k.json" --require-whole 10000 >"$TMP/check.txt" 2>&1; then
  if "$PY" - "$TMP/k.json" "$TMP/k_0.vtu" "$TMP/k_1.vtu" <<'EOF2'
import json, re, sys
d = json.load(open(sys.argv[1]))["dist"]
final = sum(g["tets"] for g in d["per_rank"])
peaks = [g["peak_tets"] / final for g in d["per_rank"]]
# the pieces as written: each about half the output tets (the balance after the tasks; 10% slack
# for the subregions' grain), read from the files, not the report
cells = [int(re.search(rb'NumberOfCells="(\d+)"', open(f, "rb").read(4096)).group(1)) for f in sys.argv[2:]]
spread = max(cells) * len(cells) / sum(cells)
print("   depth %d; peak held per rank: %s of %d tets; tasks %s; pieces %s tets (%.2f times the mean)" % (d["depth"],
      ", ".join("%.0f%%" % (100 * p) for p in peaks), final, [g["tasks"] for g in d["per_rank"]], cells, spread))
sys.exit(0 if max(peaks) <= 0.75 and min(g["tasks"] for g in d["per_rank"]) > 0 and spread <= 1.10 else 1)
EOF2
  then echo "ok   knee_atlas.nrrd, 2 ranks: every guarantee, no rank held more than 75% of the tets, pieces balanced"
  else echo "FAIL knee_atlas.nrrd, 2 ranks: a rank held more than 75% of the final tets (or ran no task, or a piece holds more than 1.1 times the mean)"; fail=1; fi
else
  echo "FAIL knee_atlas.nrrd, 2 ranks: i2m failed or a guarantee is broken"; tail -5 "$TMP/log"; grep VIOLATED "$TMP/check.txt"; fail=1
fi

# --sliver-angle under MPI: the slivers treated as tasks, every guarantee kept; deterministic:
# the same mesh at 1 and 2 ranks
for run in "2 2 async" "1 1 det" "2 1 det"; do
  set -- $run
  det=; [ "$3" = det ] && det=--deterministic
  if timeout 300 $MPIRUN -np "$1" "$BIN/i2m" "$TMP/shells.nrrd" -o "$TMP/s.pvtu" --depth 2 --threads "$2" $det --sliver-angle 10 \
    --quiet --report "$TMP/s$1$3.json" >"$TMP/log" 2>&1 &&
    check_guarantees "$TMP/s.pvtu" "$TMP/shells.nrrd" "$TMP/s$1$3.json" --require-whole 10000 >"$TMP/check.txt" 2>&1 &&
    figs=$("$PY" -c "
import json, sys
r = json.load(open(sys.argv[1])); v = r['slivers']
assert v['after'] < v['before'] / 10 and v['min_dihedral_after'] > v['min_dihedral_before'], v
print('%d -> %d slivers below 10 deg, smallest %.3g -> %.3g deg, checksum %s' % (v['before'], v['after'], v['min_dihedral_before'], v['min_dihedral_after'], r['counts']['checksum']))" "$TMP/s$1$3.json"); then
    echo "ok   shells.nrrd --sliver-angle 10, $1 ranks x $2 threads $3: every guarantee; $figs"
  else
    echo "FAIL shells.nrrd --sliver-angle 10, $1 ranks x $2 threads $3"; tail -3 "$TMP/log"; grep VIOLATED "$TMP/check.txt"; fail=1
  fi
done
if [ "$(checksum "$TMP/s1det.json" 2>/dev/null)" = "$(checksum "$TMP/s2det.json" 2>/dev/null)" ]; then
  echo "ok   shells.nrrd --sliver-angle 10 --deterministic: the same checksum at 1 and 2 ranks"
else echo "FAIL shells.nrrd --sliver-angle 10 --deterministic: checksums differ at 1 and 2 ranks"; fail=1; fi

# --deterministic: one mesh, whoever makes it.  The knee at delta 1.5: two rounds of the
# component rule (83 and 40 bridge points, one of them left to a wide task), where one process
# once inserted the points in another order than the ranks' tasks (the elements they make wait
# according to the neighbours there are when they go in)
for spec in "$TMP/shells.nrrd:" "$DATA/vertebrae_vbseg.mha:" "$DATA/knee_atlas.nrrd:--delta 1.5"; do
  img=${spec%%:*} opts=${spec#*:}
  name=$(basename "$img")
  timeout 300 "$BIN/i2m" "$img" -o "$TMP/d.vtu" --deterministic --threads 2 $opts --quiet --report "$TMP/d0.json" 2>"$TMP/log"
  want=$(checksum "$TMP/d0.json")
  runs="1 1,1 2,2 1,2 2,4 1"
  [ "$name" = shells.nrrd ] || runs="2 2,4 1" # (the real images: two of them, one for the knee)
  [ "$name" = knee_atlas.nrrd ] && runs="2 1"
  IFS=,
  for run in $runs; do
    IFS=" "
    set -- $run
    if ! timeout 300 $MPIRUN -np "$1" "$BIN/i2m" "$img" -o "$TMP/d.vtu" --deterministic --threads "$2" $opts --quiet \
      --report "$TMP/d.json" >"$TMP/log" 2>&1; then
      echo "FAIL $name deterministic, $1 ranks x $2 threads: i2m failed"; tail -5 "$TMP/log"; fail=1; continue
    fi
    got=$(checksum "$TMP/d.json")
    spread=$(spread "$TMP/d.json")
    if [ "$got" = "$want" ]; then echo "ok   $name deterministic, $1 ranks x $2 threads: checksum $got, as one process"
    else echo "FAIL $name deterministic, $1 ranks x $2 threads: checksum $got, one process $want"; fail=1; fi
    case $spread in
    ok*) echo "ok   $name deterministic, $1 ranks x $2 threads: ${spread#ok }" ;;
    *) echo "FAIL $name deterministic, $1 ranks x $2 threads: $spread"; fail=1 ;;
    esac
  done
done
exit $fail
