#!/bin/sh
# i2m-check on distributed meshes (.pvtu): the pieces stitched by GlobalNodeId.  A mesh of a
# synthetic image, split into 3 pieces by tests/scripts/pvtu_split.py, passes with the figures
# of the single .vtu (validity, quality, fidelity); each stitching error makes it fail (exit 1)
# with its "STITCH ERROR:" line and defect name: one global id at two points, two ids at one
# point, a piece without ids, a face seen by one side only; a missing piece file is unreadable
# (exit 2, one line naming it).  With mpirun, a .pvtu written by 2 ranks passes too.  Runs
# $I2M_BIN/i2m-check, and build/asan/bin/i2m-check when it exists (or $I2M_ASAN_BIN).
set -u
BIN="${I2M_BIN:-bin}"
PY="${PYTHON:-/usr/bin/python3}"
SPLIT="$(dirname "$0")/pvtu_split.py"
ASAN_CK="${I2M_ASAN_BIN:-build/asan/bin}/i2m-check"
T="$I2M_TMP/pvtu"
mkdir -p "$T"
fail=0
say() { printf '%s\n' "$*"; }
bad() { say "FAIL: $*"; fail=1; }

"$BIN/i2m-mkimage" --shape shells --dims 32,32,32 -o "$T/s.nrrd" > /dev/null || { say "FAIL: i2m-mkimage"; exit 1; }
"$BIN/i2m" "$T/s.nrrd" -o "$T/s.vtu" --quiet || { say "FAIL: i2m on s.nrrd"; exit 1; }

# split CASE KIND: $T/CASE/m.pvtu and its pieces
split() {
  mkdir -p "$T/$1"
  "$PY" "$SPLIT" "$T/s.vtu" "$T/$1/m.pvtu" --pieces 3 --break "$2" > "$T/$1/what.txt" ||
    bad "pvtu_split.py --break $2 failed"
}
split good none
split coords coords
split shared shared
split noids noids
split onesided onesided
split missing missing

# the stitched mesh has the single file's figures
good() {
  ck=$1
  "$ck" "$T/s.vtu" --json --image "$T/s.nrrd" --no-distances --require-whole 100 > "$T/one.json" ||
    bad "$ck s.vtu: not a pass"
  "$ck" "$T/good/m.pvtu" --json --image "$T/s.nrrd" --no-distances --require-whole 100 > "$T/good.json" ||
    bad "$ck good/m.pvtu: not a pass"
  "$PY" - "$T/one.json" "$T/good.json" <<'EOF' || bad "$ck good/m.pvtu: figures differ from s.vtu"
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
va, vb = a['validity'], b['validity']
st = b['stitch']
assert a['stitch'] is None and b['mesh']['format'] == 'pvtu'
assert b['valid'] and b['passed'] and va['errors'] == vb['errors'] == []
for k in ('vertices', 'tetrahedra'):
    assert a['mesh'][k] == b['mesh'][k], k
for k in ('interior_faces', 'boundary_faces', 'boundary_edges', 'interface_triangles', 'interface_pairs'):
    assert va[k] == vb[k], k
assert abs(va['total_volume'] - vb['total_volume']) <= 1e-9 * va['total_volume']
for k in ('min_dihedral', 'max_dihedral', 'max_radius_edge', 'min_planar_angle'):
    assert a['quality'][k] == b['quality'][k], k
for la, lb in zip(a['fidelity']['labels'], b['fidelity']['labels']):
    for k in ('label', 'tets', 'mesh_components', 'split_components'):
        assert la[k] == lb[k], k
assert len(st['pieces']) == 3 and all(p['global_ids'] for p in st['pieces'])
assert sum(p['tetrahedra'] for p in st['pieces']) == b['mesh']['tetrahedra']
assert st['vertices_before'] == sum(p['vertices'] for p in st['pieces']) > st['vertices_after']
assert st['vertices_after'] == b['mesh']['vertices'] and st['seam_vertices'] > 0
assert st['seams_checked'] and st['one_sided_faces'] == 0 and st['errors'] == []
EOF
  "$ck" "$T/good/m.pvtu" > "$T/good.txt" || bad "$ck good/m.pvtu (text): not a pass"
  grep -q '^  piece 2: .*/m_2.vtu: [0-9]* vertices, [0-9]* tets$' "$T/good.txt" || bad "no piece line"
  grep -q '^stitch: 3 pieces, [0-9]* vertices before merging, [0-9]* after, [0-9]* seam vertices' \
    "$T/good.txt" || bad "no stitch summary"
  say "ok   good/m.pvtu: passes with the figures of s.vtu"
}

# broken CHECKER CASE DEFECT TEXT: exit 1, the defect in the JSON, "STITCH ERROR: TEXT" printed
broken() {
  ck=$1
  "$ck" "$T/$2/m.pvtu" > "$T/$2/out.txt" 2> "$T/$2/err.txt"
  code=$?
  [ $code = 1 ] || { bad "$ck $2/m.pvtu: exit $code, expected 1 ($(head -c 300 "$T/$2/err.txt"))"; return; }
  line=$(grep "^STITCH ERROR: $4" "$T/$2/out.txt")
  [ -n "$line" ] || { bad "$2: no 'STITCH ERROR: $4' line"; return; }
  "$ck" "$T/$2/m.pvtu" --json > "$T/$2/out.json"
  "$PY" -c "import json,sys; j=json.load(open(sys.argv[1])); assert not j['valid'] and '$3' in j['validity']['errors'] and j['stitch']['errors']" \
    "$T/$2/out.json" || bad "$2: JSON without $3"
  say "ok   $2: $line"
}

for ck in "$BIN/i2m-check" "$ASAN_CK"; do
  [ -x "$ck" ] || continue
  say "== $ck"
  good "$ck"
  # the messages name the global ids and pieces pvtu_split.py broke
  g=$(sed 's/global id \([0-9]*\) .*/\1/' "$T/coords/what.txt")
  broken "$ck" coords stitch_coordinate_mismatch \
    "global ids with different coordinates in two pieces: 1; first: global id $g is at (.*) in piece 0 (.*m_0.vtu) but at (.*) in piece 1 (.*m_1.vtu)$"
  set -- $(sed 's/global ids \([0-9]*\) and \([0-9]*\) .*/\1 \2/' "$T/shared/what.txt")
  broken "$ck" shared stitch_shared_point \
    "points with two global ids: 1; first: global ids $1 (piece 0, .*) and $2 (piece 1, .*) are at the same point"
  broken "$ck" noids stitch_no_global_ids \
    "pieces without GlobalNodeId: 1; first: piece 1 (.*m_1.vtu) has no GlobalNodeId point data"
  broken "$ck" onesided stitch_one_sided_face \
    "faces seen by one side only: 1; first: the face of global ids .* (tet [0-9]* of piece 0, .*m_0.vtu) is on the boundary of the stitched mesh, but its outer side lies in tet [0-9]* of piece 1"
  # the one-sided face is the one split, and nothing else is wrong
  "$PY" -c "import json,sys; j=json.load(open(sys.argv[1])); v=j['validity']; assert v['errors'] == ['stitch_one_sided_face'] and j['stitch']['one_sided_faces'] == 1; assert sorted(j['stitch']['errors'][0].split('global ids ')[1].split(' (')[0].split()) == sorted(sys.argv[2].split())" \
    "$T/onesided/out.json" "$(sed 's/face of global ids \(.*\) split.*/\1/' "$T/onesided/what.txt")" ||
    bad "onesided: not exactly the split face"
  # a missing piece: unreadable, one line naming the .pvtu and the piece
  "$ck" "$T/missing/m.pvtu" > /dev/null 2> "$T/missing/err.txt"
  code=$?
  [ $code = 2 ] || bad "missing piece: exit $code, expected 2"
  grep -q "^i2m-check: .*missing/m.pvtu: piece 3 of 4: .*missing/m_3.vtu: cannot open" "$T/missing/err.txt" &&
    [ "$(wc -l < "$T/missing/err.txt")" = 1 ] || bad "missing piece: not one line naming it: $(cat "$T/missing/err.txt")"
  say "ok   missing piece: $(cat "$T/missing/err.txt")"
done

# a .pvtu written by 2 MPI ranks (when mpirun runs here)
if command -v mpirun > /dev/null 2>&1; then
  root=""
  [ "$(id -u)" = 0 ] && root="--allow-run-as-root"
  if OMP_NUM_THREADS=1 timeout 300 mpirun $root --oversubscribe -np 2 "$BIN/i2m" "$T/s.nrrd" -o "$T/mpi.pvtu" --quiet > "$T/mpi.log" 2>&1; then
    "$BIN/i2m-check" "$T/mpi.pvtu" > "$T/mpi.txt" || bad "mpirun -np 2: i2m-check fails: $(grep -i 'error\|invalid' "$T/mpi.txt" | head -3)"
    say "ok   mpirun -np 2: $(grep '^stitch:' "$T/mpi.txt")"
  else
    say "skip mpirun -np 2 (i2m under mpirun failed: $(tail -n 1 "$T/mpi.log"))"
  fi
else
  say "skip mpirun part (no mpirun)"
fi

[ $fail = 0 ] && say "test_check_pvtu: all passed"
exit $fail
