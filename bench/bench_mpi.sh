#!/bin/sh
# Distributed benchmark: one image meshed over a sweep of ranks x threads, the paper's Table 2
# (cores, ranks, threads, elements, time, elements/s, speedup against 1x1, efficiency) and,
# from the best run of each MPI configuration, its Fig. 7 breakdown averaged over the ranks
# (pre-processing, meshing, communication, idle, as fractions of each rank's time) and the
# bytes moved per output tet, where the communication time goes (waiting for data, packing,
# joining, dropping, merging), and, from its --trace, how long tasks ran on every rank, on some
# only (the others waiting: the tail) and on none.  Writes bench/results/bench_mpi_<date>.txt
# and .json.
#
#   bench/bench_mpi.sh [-i IMAGE] [-o "I2M OPTIONS"] [-r REPEATS] [-c "CONFIGS"]
#
#   -i  the image (I2M_BENCH_IMAGE; default the knee atlas, $I2M_DATA/knee_atlas.nrrd)
#   -o  i2m options (I2M_BENCH_OPTS; default "--delta 0.33": about 6 M tets on the knee)
#   -r  runs of each configuration, best kept (I2M_BENCH_REPEATS; default 3)
#   -c  configurations (I2M_BENCH_CONFIGS; default "1x1 1x2 mpi1x1 2x1 2x2 4x1"):
#       RxT = R ranks of T threads; 1xT is a plain process (no launcher), mpi1xT one rank
#       under the launcher; R > 1 always runs under it (run/mpirun.sh: MPIRUN, I2M)
#
# The runs go round robin over the configurations (this machine's speed drifts by +-25%:
# never all repeats of one configuration in a row), and each configuration keeps its fastest
# run by i2m's own wall clock (the report's total: reading to writing, without the launcher's
# start-up, which the table shows apart).  Configurations with more threads in all than
# cores are marked oversubscribed ("*").  Speedup is against the first plain 1x1 (else the
# first configuration); efficiency = speedup / cores.
set -eu
cd "$(dirname "$0")/.."
DATA=${I2M_DATA:-../shared/data}
IMAGE=${I2M_BENCH_IMAGE:-$DATA/knee_atlas.nrrd}
OPTS=${I2M_BENCH_OPTS:---delta 0.33}
REPEATS=${I2M_BENCH_REPEATS:-3}
CONFIGS=${I2M_BENCH_CONFIGS:-1x1 1x2 mpi1x1 2x1 2x2 4x1}
PY=${PYTHON:-/usr/bin/python3}
while getopts i:o:r:c:h opt; do
  case $opt in
    i) IMAGE=$OPTARG ;;
    o) OPTS=$OPTARG ;;
    r) REPEATS=$OPTARG ;;
    c) CONFIGS=$OPTARG ;;
    *) sed -n '10,17p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2 ;;
  esac
done
export I2M="${I2M:-$(pwd)/bin/i2m}"
[ -x "$I2M" ] || { echo "bench_mpi: no $I2M (run make first)" >&2; exit 2; }
[ -f "$IMAGE" ] || { echo "bench_mpi: no image $IMAGE (set I2M_BENCH_IMAGE or I2M_DATA)" >&2; exit 2; }
case $REPEATS in '' | *[!0-9]* | 0) echo "bench_mpi: -r takes a positive integer" >&2; exit 2 ;; esac
for c in $CONFIGS; do
  case ${c#mpi} in [1-9]*x[1-9]*) ;; *) echo "bench_mpi: bad configuration '$c' (RxT or mpi1xT)" >&2; exit 2 ;; esac
done

OUT=bench/results
mkdir -p "$OUT"
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
stamp=$(date +%Y%m%d-%H%M%S)
cores=$(sh run/mpirun.sh -d -n 1 -t 1 x y 2>&1 >/dev/null | sed -n 's/.* on \([0-9]*\) core(s).*/\1/p')
[ -n "$cores" ] || cores=$(getconf _NPROCESSORS_ONLN 2>/dev/null || echo 1)

# seconds since the epoch, with a fraction when date gives one
now() {
  s=$(date +%s.%N)
  case $s in *N) s=$("$PY" -c 'import time; print(time.time())') ;; esac
  echo "$s"
}

# one run of configuration $1; its report in $TMP/run.json, its wall clock in $TMP/run.wall
run_one() {
  c=$1
  rt=${c#mpi}
  r=${rt%x*}
  t=${rt#*x}
  rm -f "$TMP"/out* "$TMP/run.trace"
  # shellcheck disable=SC2086
  if [ "$c" = "$rt" ] && [ "$r" = 1 ]; then
    set -- env OMP_NUM_THREADS="$t" "$I2M" "$IMAGE" -o "$TMP/out.vtu" --threads "$t"
  else
    set -- sh run/mpirun.sh -n "$r" -t "$t" "$IMAGE" "$TMP/out.pvtu" --threads "$t" --trace "$TMP/run.trace"
  fi
  t0=$(now)
  # shellcheck disable=SC2086
  if ! "$@" $OPTS --quiet --report "$TMP/run.json" >"$TMP/log" 2>&1; then
    echo "bench_mpi: configuration $c failed:" >&2
    tail -n 20 "$TMP/log" >&2
    exit 1
  fi
  t1=$(now)
  "$PY" -c 'import sys; print(float(sys.argv[2]) - float(sys.argv[1]))' "$t0" "$t1" >"$TMP/run.wall"
  rm -f "$TMP"/out*
}

echo "bench_mpi: $IMAGE, options '$OPTS', $REPEATS round(s) of: $CONFIGS ($cores cores)"
round=1
while [ "$round" -le "$REPEATS" ]; do
  for c in $CONFIGS; do
    run_one "$c"
    best="$TMP/best_$c.json"
    "$PY" - "$TMP/run.json" "$TMP/run.wall" "$best" "$c" "$round" "$TMP/run.trace" <<'PY'
import json, shutil, sys
run, wall, best, cfg, rnd, trace = sys.argv[1:]
r = json.load(open(run))
r["bench_wall_seconds"] = float(open(wall).read())


def overlap(path, ranks):
    """Seconds of the tasks' span (first start to last end, the trace's clock) during which every
    rank, only some, or none ran a batch of tasks (a rank's tasks of one batch share their times)."""
    events = []
    seen = set()
    for line in open(path):
        if line.startswith("#") or not line.strip():
            continue
        f = line.split()
        key = (int(f[0]), f[3], f[4])
        if key not in seen:
            seen.add(key)
            events += [(float(f[3]), 1), (float(f[4]), -1)]
    events.sort()
    out = {"all": 0.0, "some": 0.0, "none": 0.0}
    running, last = 0, None
    for t, d in events:
        if last is not None and t > last:
            out["all" if running >= ranks else "some" if running > 0 else "none"] += t - last
        running, last = running + d, t
    out["span"] = sum(out.values())
    return out


try:
    r["bench_overlap"] = overlap(trace, r["dist"]["ranks"])
except (OSError, KeyError, ValueError, IndexError):
    pass
t = r["time_seconds"]["total"]
bridged = r["refinement"].get("bridge_rounds", 0)  # (the component rule's rounds: a piece pass more each)
try:
    b = json.load(open(best))
    times, rounds = b["bench_times"] + [t], b["bench_bridge_rounds"] + [bridged]
    keep = t < b["time_seconds"]["total"]
except FileNotFoundError:
    times, rounds, keep = [t], [bridged], True
if not keep:
    r = b
r["bench_times"], r["bench_bridge_rounds"] = times, rounds
json.dump(r, open(best, "w"))
print("  round %s  %-7s %10d tets  %7.2f s (launch to exit %6.2f s)%s%s" % (
    rnd, cfg, json.load(open(run))["counts"]["tetrahedra"], t, float(open(wall).read()),
    ", %d bridge round(s)" % bridged if bridged else "", "  (best so far)" if keep and times[1:] else ""))
PY
  done
  round=$((round + 1))
done

# shellcheck disable=SC2086
"$PY" - "$TMP" "$cores" "$IMAGE" "$OPTS" "$REPEATS" "$OUT/bench_mpi_$stamp" $CONFIGS <<'PY'
import json, os, socket, sys, time
tmp, cores, image, opts, repeats, base = sys.argv[1:7]
configs, cores = sys.argv[7:], int(cores)
rows = []
for c in configs:
    r = json.load(open(f"{tmp}/best_{c}.json"))
    rt = c[3:] if c.startswith("mpi") else c
    ranks, threads = (int(x) for x in rt.split("x"))
    mpi = c.startswith("mpi") or ranks > 1
    row = {"config": c, "ranks": ranks, "threads": threads, "cores": ranks * threads,
           "launch": "mpirun" if mpi else "plain", "oversubscribed": ranks * threads > cores,
           "elements": r["counts"]["tetrahedra"], "time_seconds": r["time_seconds"]["total"],
           "times": r["bench_times"], "bridge_rounds": r["bench_bridge_rounds"], "refinement_seconds": r["time_seconds"]["refinement"],
           "launch_to_exit_seconds": r["bench_wall_seconds"], "checksum": r["counts"]["checksum"],
           "peak_rss_bytes": r["memory"]["peak_rss_bytes"]}
    row["elements_per_second"] = row["elements"] / row["time_seconds"]
    d = r.get("dist")
    if d:
        fr = {"preprocess": 0.0, "meshing": 0.0, "communication": 0.0, "idle": 0.0}
        for g in d["per_rank"]:
            parts = {"preprocess": g["preprocess_seconds"], "meshing": g["meshing_seconds"],
                     "communication": g["comm_seconds"], "idle": g["idle_seconds"]}
            total = sum(parts.values()) or 1.0
            for k in fr:
                fr[k] += parts[k] / total / len(d["per_rank"])
        row["breakdown"] = fr
        cp = {k: 0.0 for k in ("wait_data", "pack", "unpack", "drop", "merge")}
        for g in d["per_rank"]:
            for k in cp:
                cp[k] += g["comm_parts_seconds"][k] / len(d["per_rank"])
        row["comm_parts_seconds"] = cp
        row["bytes_per_tet"] = d["bytes"] / row["elements"] if row["elements"] else 0.0
        row["depth"], row["tasks"], row["submeshes_moved"] = d["depth"], d["tasks"], d["submeshes_moved"]
        if "bench_overlap" in r and ranks > 1:
            row["task_overlap_seconds"] = r["bench_overlap"]
    rows.append(row)
ref = next((w for w in rows if w["config"] == "1x1"), rows[0])
for w in rows:
    w["speedup"] = ref["time_seconds"] / w["time_seconds"]
    w["efficiency"] = w["speedup"] / w["cores"]

lines = [f"i2m bench_mpi {time.strftime('%Y-%m-%d %H:%M')} on {socket.gethostname()} ({cores} cores)",
         f"image {image}, options '{opts}', best of {repeats} interleaved run(s); time = i2m's wall clock (report total)",
         "",
         "Table 2: cores ranks threads   elements   time (s)   elements/s  speedup  efficiency  launch   (launch to exit, s)",
         "-" * 110]
for w in rows:
    lines.append("        %5d %5d %7d %10d %10.2f %12.0f %8.2f %11.2f  %-7s%s %8.2f" % (
        w["cores"], w["ranks"], w["threads"], w["elements"], w["time_seconds"], w["elements_per_second"],
        w["speedup"], w["efficiency"], w["launch"], "*" if w["oversubscribed"] else " ", w["launch_to_exit_seconds"]))
lines.append("  (*: oversubscribed, more threads than the %d cores; speedup against %s)" % (cores, ref["config"]))
lines += ["", "Every run, seconds in the order run (b: the component rule found a tissue split and ran a bridge",
          "round, tasks and a pass over the pieces more; it comes by chance, in one process too):"]
for w in rows:
    lines.append("  %-7s %s" % (w["config"], "  ".join("%6.2f%s" % (t, "b" if k else " ")
                                                      for t, k in zip(w["times"], w["bridge_rounds"]))))
lines += ["", "Fig. 7 breakdown of the best run, averaged over ranks (fractions of each rank's time):",
          "  config   pre-processing  meshing  communication   idle   bytes moved/tet  depth  tasks",
          "  " + "-" * 88]
for w in rows:
    if "breakdown" in w:
        b = w["breakdown"]
        lines.append("  %-7s %15.3f %8.3f %14.3f %6.3f %17.1f %6d %6d" % (
            w["config"], b["preprocess"], b["meshing"], b["communication"], b["idle"], w["bytes_per_tet"],
            w["depth"], w["tasks"]))
    else:
        lines.append("  %-7s   (plain process: no MPI breakdown)" % w["config"])


def seconds_table(title, header, key, fields, fmt):
    """A table of the rows that have the figures `key`, one line each: config, then fields."""
    out = [""] + title + [header, "  " + "-" * (len(header) - 2)]
    for w in rows:
        if key in w:
            out.append(("  %-7s " + fmt) % ((w["config"],) + tuple(w[key][f] for f in fields)))
    return out


lines += seconds_table(["Communication work of the best run, seconds per rank (mean over ranks; packing also while",
                        "the rank's threads refine):"],
                       "  config   waiting for data   packing  joining  dropping  merging", "comm_parts_seconds",
                       ("wait_data", "pack", "unpack", "drop", "merge"), "%18.2f %9.2f %8.2f %9.2f %8.2f")
lines += seconds_table(["Tasks running (from the best run's --trace, seconds of the tasks' span, the component rule's",
                        "pauses included in 'none'): on every rank, on some only (a rank waits: the tail), on none:"],
                       "  config   every rank    some only      none      span", "task_overlap_seconds",
                       ("all", "some", "none", "span"), "%11.2f %12.2f %9.2f %9.2f")
text = "\n".join(lines) + "\n"
print(text, end="")
open(base + ".txt", "w").write(text)
json.dump({"benchmark": "mpi", "date": time.strftime("%Y-%m-%dT%H:%M:%S"), "host": socket.gethostname(),
           "cores": cores, "input": os.path.basename(image), "options": opts, "repeats": int(repeats),
           "baseline": ref["config"], "runs": rows}, open(base + ".json", "w"), indent=1)
print(f"written to {base}.txt and {base}.json")
PY
