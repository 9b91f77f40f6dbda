#!/bin/sh
# Output files appear whole or not at all, and never replace what they must not:
#  - -o, its interfaces file (a .vtu's NAME.interfaces.vtu), --report, --trace and the input
#    may not name the same file (as files: a symbolic link or another spelling of the path
#    counts), and the report's name ends in .json;
#  - a write that fails (a file-size limit) keeps the previous file of that name, byte for
#    byte, exits 1 with one line, and leaves no temporary behind;
#  - SIGTERM or SIGHUP in the middle of writing (the moment the temporary appears) or at a
#    random moment leaves either the previous file or the complete new one, never a part,
#    and no temporary;
#  - an output that is a symbolic link keeps pointing at the file, which is replaced;
#  - JSON reports stay valid for a region with huge bounds and a label table with
#    non-UTF-8 bytes, and the cross-section SVG escapes the table's names.
set -u
B=${I2M_BIN:-bin}
T=${I2M_TMP:-$(mktemp -d)}
PY=${PYTHON:-/usr/bin/python3}
fails=0
ok() { echo "ok   $*"; }
bad() { echo "FAIL $*"; fails=$((fails + 1)); }

"$B/i2m-mkimage" -o "$T/img.nrrd" --shape shells --dims 60,60,60 >/dev/null || { bad "mkimage"; exit 1; }
"$B/i2m-mkimage" -o "$T/small.nrrd" >/dev/null || { bad "mkimage"; exit 1; }
RUN="--deterministic --threads 1 --quiet"
# shellcheck disable=SC2086
"$B/i2m" "$T/img.nrrd" -o "$T/new.vtu" $RUN || bad "reference run"
# shellcheck disable=SC2086
"$B/i2m" "$T/small.nrrd" -o "$T/old.vtu" $RUN || bad "old-file run"
cmp -s "$T/new.vtu" "$T/old.vtu" && bad "the two reference meshes should differ"

# expect_refused DESCRIPTION WORD ARGS...: exit 2, one line naming WORD, the old file intact
expect_refused() {
  what=$1 word=$2
  shift 2
  cp "$T/old.vtu" "$T/out.vtu"
  "$B/i2m" "$@" --quiet >"$T/o" 2>"$T/e"
  rc=$?
  if [ $rc -eq 2 ] && [ "$(wc -l <"$T/e")" -eq 1 ] && grep -q -- "$word" "$T/e" && cmp -s "$T/out.vtu" "$T/old.vtu" &&
    cmp -s "$T/img.nrrd.keep" "$T/img.nrrd"; then
    ok "refused: $what ($(cat "$T/e"))"
  else
    bad "$what: exit $rc, stderr: $(cat "$T/e")"
  fi
}
cp "$T/img.nrrd" "$T/img.nrrd.keep"
ln -s out.vtu "$T/link.json"
mkdir -p "$T/sub"
expect_refused "report = -o" "same file" "$T/img.nrrd" -o "$T/out.vtu" --report "$T/out.vtu"
expect_refused "report = input" "same file" "$T/img.nrrd" -o "$T/out.vtu" --report "$T/img.nrrd"
expect_refused "report = -o through a link" "same file" "$T/img.nrrd" -o "$T/out.vtu" --report "$T/link.json"
expect_refused "report = -o spelt another way" "same file" "$T/img.nrrd" -o "$T/out.vtu" --report "$T/sub/../out.vtu"
expect_refused "trace = report" "same file" "$T/img.nrrd" -o "$T/out.vtu" --report "$T/r.json" --trace "$T/r.json"
expect_refused "report not .json" ".json" "$T/img.nrrd" -o "$T/out.vtu" --report "$T/report.txt"
expect_refused "--region with an infinite corner" "finite" "$T/img.nrrd" -o "$T/out.vtu" --region "0,0,0,inf,1,1:1"
expect_refused "--threads above the limit" "threads" "$T/img.nrrd" -o "$T/out.vtu" --threads 2000
# the interfaces file that comes with a .vtu (.pvtu) output: NAME.interfaces.vtu (.pvtu)
cp "$T/img.nrrd" "$T/in.interfaces.vtu"
mkdir -p "$T/dir.interfaces.pvtu"
expect_refused "trace = the interfaces file of -o" "same file" "$T/img.nrrd" -o "$T/out.vtu" --trace "$T/out.interfaces.vtu"
expect_refused "input = the interfaces file of -o" "same file" "$T/in.interfaces.vtu" -o "$T/in.vtu"
expect_refused "the interfaces file of -o is a directory" "directory" "$T/img.nrrd" -o "$T/dir.pvtu"

# no_temporary LABEL: nothing like out.vtu.tmp* left in $T
no_temporary() {
  left=$(find "$T" -name '*.tmp[0-9]*' | head -n 3)
  [ -z "$left" ] || bad "$1: temporaries left behind: $left"
}

# a failed write: the file-size limit (in 512-byte blocks in sh) below the mesh's size
cp "$T/old.vtu" "$T/out.vtu"
# shellcheck disable=SC2086
(ulimit -f 40 && exec "$B/i2m" "$T/img.nrrd" -o "$T/out.vtu" $RUN) 2>"$T/e"
rc=$?
if [ $rc -eq 1 ] && [ "$(wc -l <"$T/e")" -eq 1 ] && cmp -s "$T/out.vtu" "$T/old.vtu"; then
  ok "a failed write keeps the previous file ($(cat "$T/e"))"
else
  bad "failed write: exit $rc, stderr: $(cat "$T/e"), previous file $(cmp -s "$T/out.vtu" "$T/old.vtu" && echo kept || echo changed)"
fi
no_temporary "failed write"
(ulimit -f 40 && exec "$B/i2m" "$T/img.nrrd" -o "$T/out.pvtu" --quiet) 2>/dev/null && bad "a .pvtu beyond the size limit succeeded"
no_temporary "failed .pvtu write"

# an output that is a symbolic link: the file it names is replaced, the link stays
cp "$T/old.vtu" "$T/target.vtu"
ln -s target.vtu "$T/link.vtu"
# shellcheck disable=SC2086
"$B/i2m" "$T/img.nrrd" -o "$T/link.vtu" $RUN || bad "writing through a link"
if [ -L "$T/link.vtu" ] && cmp -s "$T/target.vtu" "$T/new.vtu"; then ok "a linked output: the link kept, its file replaced"
else bad "a linked output: link $( [ -L "$T/link.vtu" ] && echo kept || echo replaced), target $(cmp -s "$T/target.vtu" "$T/new.vtu" && echo new || echo old)"; fi
no_temporary "linked output"

# signals: once the moment the temporary appears, and at random moments
whole_or_old() { cmp -s "$T/out.vtu" "$T/old.vtu" || cmp -s "$T/out.vtu" "$T/new.vtu"; }
for sig in TERM HUP; do
  cp "$T/old.vtu" "$T/out.vtu"
  # shellcheck disable=SC2086
  "$B/i2m" "$T/img.nrrd" -o "$T/out.vtu" $RUN &
  pid=$!
  n=0
  while [ -z "$(find "$T" -maxdepth 1 -name 'out.vtu.tmp*' 2>/dev/null)" ] && kill -0 $pid 2>/dev/null; do n=$((n + 1)); done
  kill -"$sig" $pid 2>/dev/null
  wait $pid
  rc=$?
  if whole_or_old; then ok "SIG$sig while writing (exit $rc): the file is $(cmp -s "$T/out.vtu" "$T/old.vtu" && echo the previous one || echo the new one, whole)"
  else bad "SIG$sig while writing left a partial file"; fi
  no_temporary "SIG$sig while writing"
done
i=0
while [ $i -lt 6 ]; do
  cp "$T/old.vtu" "$T/out.vtu"
  # shellcheck disable=SC2086
  "$B/i2m" "$T/img.nrrd" -o "$T/out.vtu" $RUN &
  pid=$!
  sleep "$(awk -v s=$i 'BEGIN { srand(s); printf "%.3f", rand() * 1.6 }')"
  kill -TERM $pid 2>/dev/null
  wait $pid
  whole_or_old || bad "SIGTERM at a random moment (run $i) left a partial file"
  no_temporary "SIGTERM at a random moment"
  i=$((i + 1))
done
ok "SIGTERM at 6 random moments: the previous file or the whole new one each time"

# JSON valid for any input; SVG escapes the label names
# shellcheck disable=SC2086
"$B/i2m" "$T/small.nrrd" -o "$T/s.vtu" --report "$T/s.json" --region "-1e308,-1e308,-1e308,1e308,1e308,1e308:5" $RUN ||
  bad "run with a huge region"
"$PY" -c 'import json,sys; json.load(open(sys.argv[1]))' "$T/s.json" && ok "report JSON valid with a huge region" ||
  bad "report JSON invalid with a huge region"
printf '1 <script>alert(1)</script> 255 0 0 255\n2 caf\351&\"x 0 255 0 255\n' >"$T/small.ctbl"
if "$B/i2m-check" "$T/s.vtu" --image "$T/small.nrrd" --plot "$T/plot" --json >"$T/c.json" 2>"$T/e"; then :; fi
"$PY" -c 'import json,sys; json.load(open(sys.argv[1]))' "$T/c.json" && ok "i2m-check JSON valid" || bad "i2m-check JSON invalid: $(head -c 300 "$T/c.json")"
svg=$(find "$T/plot" -name '*.svg' 2>/dev/null | head -n 20)
if [ -z "$svg" ]; then
  bad "no SVG written by i2m-check --plot ($(cat "$T/e"))"
elif grep -q '<script' $svg; then
  bad "a label name came out unescaped in the SVG"
elif "$PY" -c 'import sys, xml.dom.minidom as m; [m.parse(p) for p in sys.argv[1:]]' $svg; then
  ok "SVG well-formed, label names escaped"
else
  bad "SVG not well-formed"
fi

[ $fails -eq 0 ] || { echo "$fails failure(s)"; exit 1; }
echo "output safety: all passed"
