#!/bin/sh
# A Medit mesh comes with the JSON side file NAME.mesh.json that maps every interface ref to its
# label pair (mmg drops the comment block that holds the map in the .mesh itself).  The liver
# at --delta 4 and a synthetic image with a negative label: the side file parses and matches
# the mesh as meshio reads it (medit_side_check.py: refs, label pairs = the labels of each
# triangle's tets, tet labels, the comment block).  Other formats write no side file.  The
# side file may not be the --report or --trace file, nor a directory: refused before any work
# (exit 2, nothing written).  (The MPI case, a mesh stitched on rank 0, is in
# test_orientation.sh.)
set -eu
B="${I2M_BIN:-bin}"
D="${I2M_DATA:-../shared/data}"
PY="${PYTHON:-/usr/bin/python3}"
HERE="$(dirname "$0")"
T="$I2M_TMP/side"
mkdir -p "$T"
fail=0
bad() { echo "FAIL $*"; fail=1; }

"$B/i2m" "$D/liver.inr.gz" -o "$T/liver.mesh" --delta 4 --quiet 2> /dev/null || bad "i2m liver"
"$PY" "$HERE/medit_side_check.py" "$T/liver.mesh" || bad "liver.mesh.json"
"$B/i2m-mkimage" --shape shells --dims 24,24,24 --type int16 --labels -5,3,7 -o "$T/neg.nrrd" > /dev/null
"$B/i2m" "$T/neg.nrrd" -o "$T/neg.mesh" --quiet || bad "i2m neg.nrrd"
"$PY" "$HERE/medit_side_check.py" "$T/neg.mesh" || bad "neg.mesh.json"
grep -q '"labels": \[-5, 3\]' "$T/neg.mesh.json" || bad "neg.mesh.json: no pair (-5, 3)"
grep -q '"labels": \[0, -5\]' "$T/neg.mesh.json" || bad "neg.mesh.json: the background not first in (0, -5)"

"$B/i2m" "$T/neg.nrrd" -o "$T/neg.vtu" --quiet || bad "i2m neg.nrrd -> .vtu"
[ ! -e "$T/neg.vtu.json" ] && [ ! -e "$T/neg.json" ] && echo "ok   a VTU output: no side file" ||
  bad "a side file beside a VTU mesh"

# refused_before_work ARGS...: exit 2, one error line naming the side file, no mesh written
refused_before_work() {
  rm -f "$T/x.mesh"
  set +e
  "$B/i2m" "$T/neg.nrrd" -o "$T/x.mesh" --quiet "$@" 2> "$T/err"
  code=$?
  set -e
  if [ $code = 2 ] && grep -q "x.mesh.json" "$T/err" && [ ! -e "$T/x.mesh" ]; then
    echo "ok   refused: $(head -n 1 "$T/err")"
  else
    bad "i2m -o x.mesh $*: exit $code, mesh written: $([ -e "$T/x.mesh" ] && echo yes || echo no) ($(cat "$T/err"))"
  fi
}
refused_before_work --report "$T/x.mesh.json"
refused_before_work --trace "$T/x.mesh.json"
mkdir -p "$T/x.mesh.json"
refused_before_work
rmdir "$T/x.mesh.json"

[ $fail = 0 ] && echo "medit side file: all passed"
exit $fail
