#!/bin/sh
# Limits: a run that cannot fit is refused before any work, with the estimate in one line;
# running out of memory anyway is an error (exit 1, one line), never an abort or a crash.
#  - options the header refutes (--delta beyond the image, a region outside it) exit 2
#    before the voxels are read;
#  - a tiny --delta on a small image (it used to overflow a grid and segfault, or refine for
#    minutes) and a --max-memory below the estimate are refused at once, naming the estimate;
#  - the liver at --delta 2 under address-space limits (ulimit -v) of 80 to 160 MB, at 1
#    and 2 threads and in deterministic mode: exit 0 or exit 1 with one line about memory,
#    every time (the runs that end in the middle of refinement, of the distance transform,
#    of the extraction or of the writing all count).
set -u
B=${I2M_BIN:-bin}
T=${I2M_TMP:-$(mktemp -d)}
DATA=${I2M_DATA:-../shared/data}
fails=0
bad() { echo "FAIL $*"; fails=$((fails + 1)); }

"$B/i2m-mkimage" -o "$T/tiny.nrrd" --dims 2,2,2 --shape cube >/dev/null || { bad "mkimage"; exit 1; }
start=$(date +%s)
"$B/i2m" "$T/tiny.nrrd" -o "$T/t.vtu" --delta 2.3841872121019436e-07 --quiet 2>"$T/e"
rc=$?
if [ $rc -eq 1 ] && [ "$(wc -l <"$T/e")" -eq 1 ] && grep -q "estimated at" "$T/e" && [ $(($(date +%s) - start)) -lt 10 ]; then
  echo "ok   a tiny --delta is refused up front: $(cat "$T/e")"
else
  bad "tiny --delta: exit $rc after $(($(date +%s) - start)) s: $(head -c 300 "$T/e")"
fi
"$B/i2m" "$DATA/liver.inr.gz" -o "$T/t.vtu" --max-memory 20M --quiet 2>"$T/e"
rc=$?
if [ $rc -eq 1 ] && [ "$(wc -l <"$T/e")" -eq 1 ] && grep -q "max-memory" "$T/e"; then
  echo "ok   --max-memory below the estimate is refused: $(cat "$T/e")"
else
  bad "--max-memory 20M: exit $rc: $(head -c 300 "$T/e")"
fi
"$B/i2m" "$DATA/liver.inr.gz" -o "$T/t.vtu" --max-memory 2G --quiet 2>"$T/e" || bad "--max-memory 2G refused the liver: $(cat "$T/e")"

# options that the image's header refutes are refused before its voxels are read: this
# file's gzip stream is cut short, which only reading the voxels would find
"$B/i2m-mkimage" --dims 40,40,40 --shape noise --type int16 --gzip -o "$T/cut.nrrd" --truncate-bytes 3000 >/dev/null
for opt in "--delta 1e6" "--region 500,500,500,600,600,600:1"; do
  # shellcheck disable=SC2086
  "$B/i2m" "$T/cut.nrrd" -o "$T/t.vtu" $opt --quiet 2>"$T/e"
  rc=$?
  if [ $rc -eq 2 ] && [ "$(wc -l <"$T/e")" -eq 1 ] && grep -q -- "${opt%% *}" "$T/e"; then echo "ok   $opt refused from the header: $(cat "$T/e")"
  else bad "$opt on a header whose voxels are cut: exit $rc: $(head -c 300 "$T/e")"; fi
done

n=0 ok=0 oom=0
for opts in "--threads 1" "--threads 2" "--threads 2 --deterministic"; do
  v=80000
  while [ $v -le 160000 ]; do # (every 20 MB)
    # shellcheck disable=SC2086
    (ulimit -v $v && exec "$B/i2m" "$DATA/liver.inr.gz" -o "$T/m.vtu" --delta 2 --max-memory 100G --quiet $opts) 2>"$T/e"
    rc=$?
    n=$((n + 1))
    if [ $rc -eq 0 ]; then
      ok=$((ok + 1))
    elif [ $rc -eq 1 ] && [ "$(wc -l <"$T/e")" -eq 1 ] && grep -qi "memory" "$T/e"; then
      oom=$((oom + 1))
    else
      bad "ulimit -v $v, $opts: exit $rc: $(head -c 300 "$T/e")"
    fi
    v=$((v + 20000))
  done
done
echo "ok   $n runs under memory limits: $ok finished, $oom ended with an out-of-memory error line, none aborted"
[ $oom -gt 0 ] || bad "no run ran out of memory: the limits no longer test anything"
[ $fails -eq 0 ] || { echo "$fails failure(s)"; exit 1; }
echo "limits: all passed"
