#!/bin/sh
# i2m-check on hand-made meshes: broken ones are reported invalid (exit 1, and the JSON names
# the defect) or unreadable (exit 2), never a crash; valid ones pass (exit 0) with exact
# figures; thresholds fail with a line naming them.  Meshes are written here as Medit text
# into $I2M_TMP.  Runs $I2M_BIN/i2m-check, and also build/asan/bin/i2m-check when it exists
# (ASan + UBSan; another directory with $I2M_ASAN_BIN).  When $I2M_BIN/i2m-mkimage exists, a fidelity part meshes a synthetic image
# voxel by voxel (test_io_writers with I2M_BIG_MESH, step 1: interfaces = the voxel
# staircase) and expects a Hausdorff distance of 0, then a missing label.
set -u
BIN="${I2M_BIN:-bin}"
PY="${PYTHON:-/usr/bin/python3}"
TB="${I2M_TEST_BIN:-build/release/tests}"
ASAN_CK="${I2M_ASAN_BIN:-build/asan/bin}/i2m-check"
T="$I2M_TMP/broken"
mkdir -p "$T"
fail=0
say() { printf '%s\n' "$*"; }
bad() { say "FAIL: $*"; fail=1; }

# ---- the meshes ------------------------------------------------------------------------
# unit cube [0,1]^3: corners v = 1 + x + 2y + 4z (1-based), 6 positive Kuhn tets, labels 1, 2
verts() {
  printf 'MeshVersionFormatted 2\nDimension 3\nVertices\n%s\n' "$1"
  printf '0 0 0 0\n1 0 0 0\n0 1 0 0\n1 1 0 0\n0 0 1 0\n1 0 1 0\n0 1 1 0\n1 1 1 0\n'
}
tets_ok='1 2 4 8 1
1 3 7 8 1
1 5 6 8 1
1 6 2 8 2
1 7 5 8 2
1 4 3 8 2'
{ verts 8; printf 'Tetrahedra\n6\n%s\nEnd\n' "$tets_ok"; } > "$T/cube.mesh"
# one tet inverted (two vertices swapped)
{ verts 8; printf 'Tetrahedra\n6\n%s\nEnd\n' "$(echo "$tets_ok" | sed '1s/.*/2 1 4 8 1/')"; } > "$T/inverted.mesh"
# face (1,2,4) on z=0 used three times: two more tets below it
{ verts 10; printf '0.5 0.5 -1 0\n0.2 0.6 -2 0\n'; printf 'Tetrahedra\n8\n%s\n1 4 2 9 1\n1 4 2 10 1\nEnd\n' "$tets_ok"; } > "$T/shared3.mesh"
# a tet on the same side of the cube's bottom face (1,2,4) as the first tet: the two overlap
{ verts 9; printf '0.7 0.3 0.5 0\n'; printf 'Tetrahedra\n7\n%s\n1 2 4 9 1\nEnd\n' "$tets_ok"; } > "$T/overlap.mesh"
# an unused vertex
{ verts 9; printf '5 5 5 0\n'; printf 'Tetrahedra\n6\n%s\nEnd\n' "$tets_ok"; } > "$T/dangling.mesh"
# vertex 9 = vertex 8, used by the first tet instead of 8
{ verts 9; printf '1 1 1 0\n'; printf 'Tetrahedra\n6\n%s\nEnd\n' "$(echo "$tets_ok" | sed '1s/.*/1 2 4 9 1/')"; } > "$T/duplicate.mesh"
# a vertex id beyond the 8 vertices, and one below 1
{ verts 8; printf 'Tetrahedra\n6\n%s\nEnd\n' "$(echo "$tets_ok" | sed '2s/.*/1 3 7 12 1/')"; } > "$T/range.mesh"
{ verts 8; printf 'Tetrahedra\n6\n%s\nEnd\n' "$(echo "$tets_ok" | sed '2s/.*/0 3 7 8 1/')"; } > "$T/range0.mesh"
# a tet that names one vertex twice (zero volume; all four of its faces hold its smallest id)
{ verts 8; printf 'Tetrahedra\n7\n%s\n1 1 2 3 1\nEnd\n' "$tets_ok"; } > "$T/repeat.mesh"
# a flat (zero-volume) tet: four coplanar corners of the cube's bottom face
{ verts 8; printf 'Tetrahedra\n7\n%s\n1 2 4 3 1\nEnd\n' "$tets_ok"; } > "$T/flat.mesh"
# a vertex with a NaN coordinate
{ verts 9; printf 'nan 0 0 0\n'; printf 'Tetrahedra\n7\n%s\n1 2 4 9 1\nEnd\n' "$tets_ok"; } > "$T/nan.mesh"
# interface triangles in the file that are not interfaces of the tets
{ verts 8; printf 'Tetrahedra\n6\n%s\n# i2m interface 1 = labels 0 1\nTriangles\n2\n2 3 5 1\n1 6 8 1\nEnd\n' "$tets_ok"; } > "$T/badtri.mesh"
# the right-corner tet (0,0,0) (1,0,0) (0,1,0) (0,0,1), with its 4 boundary triangles
{ printf 'MeshVersionFormatted 2\nDimension 3\nVertices\n4\n0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n'
  printf 'Tetrahedra\n1\n1 2 3 4 7\n# i2m interface 1 = labels 0 7\nTriangles\n4\n'
  printf '2 4 3 1\n1 3 4 1\n1 4 2 1\n1 2 3 1\nEnd\n'; } > "$T/corner.mesh"
# unreadable: truncated in the middle of the tets, empty, junk, unknown keyword, no file
head -c 150 "$T/cube.mesh" > "$T/truncated.mesh"
: > "$T/empty.mesh"
printf '\001\002\377garbage\000\000' > "$T/junk.mesh"
printf 'MeshVersionFormatted 2\nDimension 3\nBogus\n3\n' > "$T/keyword.mesh"
printf 'MeshVersionFormatted 2\nDimension 3\nTetra\033[2J\001\n3\n' > "$T/ctrl.mesh" # echoed as '?'
{ verts 8; printf 'Tetrahedra\n99999999999\n1 2 3\n'; } > "$T/hugecount.mesh"
# cut between two sections: without End it would read as a smaller, valid mesh
{ verts 8; printf 'Tetrahedra\n6\n%s\n' "$tets_ok"; } > "$T/noend.mesh"
# no tetrahedra at all, with and without file triangles: invalid, not a crash
{ verts 8; printf 'End\n'; } > "$T/notets.mesh"
{ verts 8; printf '# i2m interface 1 = labels 0 1\nTriangles\n1\n1 2 3 1\nEnd\n'; } > "$T/trisonly.mesh"
# the corner tet with label 0 (background): with --image, an extra label 0, not a crash
sed 's/^1 2 3 4 7$/1 2 3 4 0/' "$T/corner.mesh" > "$T/corner0.mesh"
# the corner tet with its apex 50 m away: each huge triangle gets a bounded number of samples
sed 's/^0 0 1 0$/0 0 50000 0/' "$T/corner.mesh" > "$T/far.mesh"
# the corner tet at extreme magnitudes: scaled to 1e200 (exact orientation and the figures
# must not overflow) and moved to 1e16 (where a unit step is below a double's resolution
# of the coordinates, 2: here the tet is 4e16 wide)
awk '/^[01] [01] [01] 0$/ { printf "%.17g %.17g %.17g 0\n", $1 * 1e200, $2 * 1e200, $3 * 1e200; next } { print }' \
  "$T/corner.mesh" > "$T/huge.mesh"
awk '/^[01] [01] [01] 0$/ { printf "%.17g %.17g %.17g 0\n", 1e16 + $1 * 4e16, 1e16 + $2 * 4e16, 1e16 + $3 * 4e16; next } { print }' \
  "$T/corner.mesh" > "$T/far16.mesh"
# Gmsh 4.1 ASCII corner tet from its sections (F format, E entities, N nodes, L elements);
# a section twice would be read over the first one's arrays; out of order, labels go wrong
gmsh() {
  for s in "$@"; do
    case $s in
      F) printf '$MeshFormat\n4.1 0 8\n$EndMeshFormat\n' ;;
      E) printf '$Entities\n0 0 0 1\n1 0 0 0 1 1 1 0 0\n$EndEntities\n' ;;
      N) printf '$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n' ;;
      L) printf '$Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 4\n$EndElements\n' ;;
    esac
  done
}
gmsh F E N L > "$T/gcorner.msh"
gmsh F E N L L > "$T/dupelements.msh"
gmsh F E E N L > "$T/dupentities.msh"
gmsh F E N N L > "$T/dupnodes.msh"
gmsh F N E L > "$T/lateentities.msh"
# VTU corner tet (appended raw data, UInt64 headers); in short.vtu the material array lacks
# 2 bytes and the closing tags follow at once: they must not be read as its values
"$PY" - "$T" <<'EOF'
import struct, sys
def vtu(path, cut):
    arrays = [('Float64', 'Points', struct.pack('<12d', 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1)),
              ('Int64', 'connectivity', struct.pack('<4q', 0, 1, 2, 3)),
              ('Int64', 'offsets', struct.pack('<q', 4)), ('UInt8', 'types', struct.pack('<B', 10)),
              ('Int32', 'material', struct.pack('<i', 7))]
    tags, app = [], b''
    for ty, name, data in arrays:
        comp = ' NumberOfComponents="3"' if name == 'Points' else ''
        tags.append('<DataArray type="%s" Name="%s"%s format="appended" offset="%d"/>\n'
                    % (ty, name, comp, len(app)))
        app += struct.pack('<Q', len(data)) + data
    xml = ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
           'byte_order="LittleEndian" header_type="UInt64">\n<UnstructuredGrid>\n'
           '<Piece NumberOfPoints="4" NumberOfCells="1">\n<Points>\n%s</Points>\n<Cells>\n%s%s%s'
           '</Cells>\n<CellData>\n%s</CellData>\n</Piece>\n</UnstructuredGrid>\n'
           '<AppendedData encoding="raw">\n_' % tuple(tags))
    with open(path, 'wb') as f:
        f.write(xml.encode() + app[:len(app) - cut] + b'\n</AppendedData>\n</VTKFile>\n')
vtu(sys.argv[1] + '/vcorner.vtu', 0)
vtu(sys.argv[1] + '/short.vtu', 2)
EOF

# ---- runs --------------------------------------------------------------------------------
# expect CHECKER FILE CODE [JSON-PYTHON-ASSERTION] [extra args]
expect() {
  e_ck=$1; e_f=$2; e_want=$3; e_assert=$4; shift 4
  "$e_ck" "$T/$e_f" --json "$@" > "$T/out.json" 2> "$T/err.txt"
  code=$?
  if [ "$code" != "$e_want" ]; then
    bad "$e_ck $e_f $*: exit $code, expected $e_want ($(head -c 300 "$T/err.txt"))"; return
  fi
  if [ "$e_want" = 2 ]; then
    grep -q '^i2m-check: ' "$T/err.txt" || bad "$e_f: no 'i2m-check: ' error line"
    [ "$(wc -l < "$T/err.txt")" -le 2 ] || bad "$e_f: more than one error line"
    ! LC_ALL=C grep -q '[[:cntrl:]]' "$T/err.txt" || bad "$e_f: a control character in the error line"
    say "ok   $e_f: unreadable (exit 2): $(head -n 1 "$T/err.txt")"
    return
  fi
  if [ -n "$e_assert" ]; then
    if ! "$PY" -c "import json,sys,math; j=json.load(open('$T/out.json')); v=j['validity']; q=j['quality']; assert $e_assert, 'assertion'" 2>"$T/py.txt"; then
      bad "$e_f: JSON assertion failed: $e_assert ($(tail -n 1 "$T/py.txt"))"; return
    fi
  fi
  say "ok   $e_f: exit $code"
}

run_all() {
  ck=$1
  expect "$ck" cube.mesh 0 "v['valid'] and abs(v['total_volume'] - 1) < 1e-12 and v['boundary_faces'] == 12 and v['interior_faces'] == 6 and v['boundary_closed'] and v['interface_pairs'] == 3"
  expect "$ck" corner.mesh 0 "v['valid'] and abs(v['total_volume'] - 1/6) < 1e-15 and abs(q['min_dihedral'] - math.degrees(math.acos(1/math.sqrt(3)))) < 1e-9 and abs(q['max_dihedral'] - 90) < 1e-9 and q['dihedral_histogram'][89] + q['dihedral_histogram'][90] == 3 and q['dihedral_histogram'][54] == 3 and abs(q['max_radius_edge'] - math.sqrt(3)/2) < 1e-12 and abs(q['min_planar_angle'] - 45) < 1e-9 and v['file_triangles_flipped'] == 0"
  for f in huge.mesh far16.mesh; do
    expect "$ck" $f 0 "v['valid'] and abs(q['min_dihedral'] - math.degrees(math.acos(1/math.sqrt(3)))) < 1e-9 and abs(q['max_dihedral'] - 90) < 1e-9 and abs(q['max_radius_edge'] - math.sqrt(3)/2) < 1e-12 and abs(q['min_planar_angle'] - 45) < 1e-9" --max-ratio 2 --min-facet-angle 30
  done
  expect "$ck" inverted.mesh 1 "'inverted' in v['errors'] and v['inverted'] == 1 and v['first_inverted_tet'] == 0"
  expect "$ck" shared3.mesh 1 "'nonmanifold_face' in v['errors'] and v['nonmanifold_faces'] == 1 and v['first_nonmanifold_tet'] == 0"
  expect "$ck" overlap.mesh 1 "'overlapping' in v['errors'] and v['overlapping_faces'] == 1 and v['first_overlapping_tet'] == 0"
  expect "$ck" dangling.mesh 1 "v['errors'] == ['dangling_vertex'] and v['first_dangling_vertex'] == 8"
  expect "$ck" duplicate.mesh 1 "'duplicate_vertex' in v['errors'] and v['duplicate_vertices'] == 1"
  expect "$ck" range.mesh 1 "v['errors'] == ['index_out_of_range'] and v['first_index_out_of_range_tet'] == 1 and j['quality'] is None"
  expect "$ck" range0.mesh 1 "'index_out_of_range' in v['errors']"
  expect "$ck" nan.mesh 1 "'nonfinite_vertex' in v['errors'] and v['first_nonfinite_vertex'] == 8 and j['quality'] is None"
  expect "$ck" repeat.mesh 1 "'degenerate' in v['errors'] and v['degenerate'] == 1 and v['first_degenerate_tet'] == 6 and 2 * v['interior_faces'] + v['boundary_faces'] == 28 and v['nonmanifold_faces'] == 0"
  expect "$ck" flat.mesh 1 "'degenerate' in v['errors'] and v['degenerate'] == 1 and v['first_degenerate_tet'] == 6"
  expect "$ck" badtri.mesh 1 "'file_triangle_not_interface' in v['errors'] and 'interface_missing_from_file' in v['errors'] and v['file_triangles_not_interface'] == 1 and v['file_triangle_label_mismatch'] == 1"
  for f in truncated.mesh empty.mesh junk.mesh keyword.mesh ctrl.mesh hugecount.mesh missing.mesh noend.mesh \
           dupelements.msh dupentities.msh dupnodes.msh lateentities.msh short.vtu; do
    expect "$ck" $f 2 ""
  done
  expect "$ck" notets.mesh 1 "'no_tetrahedra' in v['errors']"
  expect "$ck" trisonly.mesh 1 "'no_tetrahedra' in v['errors'] and 'file_triangle_not_interface' in v['errors']"
  expect "$ck" gcorner.msh 0 "v['valid'] and abs(v['total_volume'] - 1/6) < 1e-15"
  expect "$ck" vcorner.vtu 0 "v['valid'] and abs(v['total_volume'] - 1/6) < 1e-15"
  # thresholds
  expect "$ck" corner.mesh 1 "j['violations'] and j['violations'][0].startswith('max-ratio')" --max-ratio 0.5
  expect "$ck" corner.mesh 0 "" --max-ratio 0.9
  expect "$ck" corner.mesh 1 "'min-facet-angle' in j['violations'][0]" --min-facet-angle 50
  expect "$ck" corner.mesh 0 "" --min-facet-angle 50 --facet-angle-exceptions 0.9
  "$ck" "$T/corner.mesh" --max-ratio 0.5 > "$T/out.txt"; c=$?
  [ $c = 1 ] && grep -q 'THRESHOLD VIOLATED: max-ratio' "$T/out.txt" || bad "text output does not name the violated threshold"
  # usage errors
  "$ck" > /dev/null 2> "$T/err.txt"; [ $? = 2 ] || bad "no argument: exit not 2"
  "$ck" "$T/cube.mesh" --bogus 1 > /dev/null 2> "$T/err.txt"; [ $? = 2 ] || bad "unknown option: exit not 2"
  "$ck" "$T/cube.mesh" --max-hausdorff 1 > /dev/null 2> "$T/err.txt"; [ $? = 2 ] || bad "--max-hausdorff without --image: exit not 2"
  "$ck" "$T/cube.mesh" --image "$T/none.nrrd" > /dev/null 2> "$T/err.txt"; [ $? = 2 ] || bad "missing image: exit not 2"
  # plots
  rm -rf "$T/plots"
  "$ck" "$T/cube.mesh" --plot "$T/plots" > /dev/null || bad "--plot failed"
  for s in dihedral_histogram.svg cross_section_x.svg cross_section_y.svg cross_section_z.svg; do
    grep -q '</svg>' "$T/plots/$s" 2>/dev/null || bad "--plot: $s missing or incomplete"
  done
}

# corrupt copies of the writers' own files (binary formats): truncated and bit-flipped
if [ -x "$TB/test_io_writers" ]; then
  I2M_SAMPLE_OUT="$T" "$TB/test_io_writers" || bad "sample writing failed"
  for f in sample.vtu sample.msh sample_ascii.msh sample.mesh; do
    sz=$(wc -c < "$T/$f")
    head -c $((sz / 2)) "$T/$f" > "$T/half_$f"
    head -c $((sz - 30)) "$T/$f" > "$T/short_$f"
  done
fi

for ck in "$BIN/i2m-check" "$ASAN_CK"; do
  [ -x "$ck" ] || continue
  say "== $ck"
  run_all "$ck"
  if [ -x "$TB/test_io_writers" ]; then
    for f in sample.vtu sample.msh sample_ascii.msh sample.mesh; do
      expect "$ck" $f 0 "v['valid']"
      expect "$ck" half_$f 2 ""
      expect "$ck" short_$f 2 ""
    done
    # flip bytes all over the binary files: any exit 0/1/2 is fine, a crash is not
    for f in sample.vtu sample.msh; do
      sz=$(wc -c < "$T/$f")
      k=7
      while [ $k -lt "$sz" ]; do
        "$PY" -c "import sys; b=bytearray(open('$T/$f','rb').read()); b[$k]^=0x5a; open('$T/flip_$f','wb').write(b)"
        "$ck" "$T/flip_$f" --json > /dev/null 2>&1; c=$?
        [ $c -le 2 ] || bad "$f with byte $k flipped: exit $c (crash?)"
        k=$((k + 97))
      done
    done
    say "ok   bit-flipped binary files: no crash"
  fi
done

# ---- fidelity on a synthetic image -----------------------------------------------------------
if [ -x "$BIN/i2m-mkimage" ] && [ -x "$TB/test_io_writers" ]; then
  "$BIN/i2m-mkimage" --shape two-balls --dims 20,18,14 --spacing 0.8,0.6,1.5 --labels 3,7 -o "$T/img.nrrd" > /dev/null || bad "i2m-mkimage failed"
  "$BIN/i2m-mkimage" --shape ball --dims 20,18,14 --spacing 0.8,0.6,1.5 --labels 3 -o "$T/other.nrrd" > /dev/null || bad "i2m-mkimage failed"
  I2M_BIG_MESH="$T/img.nrrd" I2M_BIG_MESH_OUT="$T/img.vtu" I2M_BIG_MESH_STEP=1 "$TB/test_io_writers" > /dev/null || bad "voxel mesh failed"
  I2M_BIG_MESH="$T/img.nrrd" I2M_BIG_MESH_OUT="$T/img.msh" I2M_BIG_MESH_STEP=1 "$TB/test_io_writers" > /dev/null || bad "voxel mesh failed"
  I2M_BIG_MESH="$T/other.nrrd" I2M_BIG_MESH_OUT="$T/other.mesh" I2M_BIG_MESH_STEP=1 "$TB/test_io_writers" > /dev/null || bad "voxel mesh failed"
  for ck in "$BIN/i2m-check" "$ASAN_CK"; do
    [ -x "$ck" ] || continue
    for f in img.vtu img.msh; do
      expect "$ck" $f 0 "j['fidelity']['hausdorff']['max_mm'] < 1e-9 and j['fidelity']['missing_labels'] == 0 and all(abs(l['volume_error_pct']) < 1e-9 for l in j['fidelity']['labels'])" --image "$T/img.nrrd" --max-hausdorff 1e-9 --max-volume-error 1e-6 --volume-min-voxels 1 --require-labels 1
    done
    expect "$ck" other.mesh 1 "j['fidelity']['missing_labels'] >= 1 and j['fidelity']['hausdorff']['max_mm'] > 0.5 and any(s.startswith('require-labels') for s in j['violations'])" --image "$T/img.nrrd" --require-labels 1
    expect "$ck" corner0.mesh 1 "j['fidelity']['extra_labels'] == 1 and j['fidelity']['labels'][0]['label'] == 0" --image "$T/img.nrrd"
    expect "$ck" far.mesh 0 "j['fidelity']['mesh_samples'] <= 4 * 33153 and j['fidelity']['mesh_to_image']['max_mm'] > 40000" --image "$T/img.nrrd"
  done
else
  say "skip fidelity part (no i2m-mkimage or test_io_writers)"
fi

[ $fail = 0 ] && say "test_check_broken: all passed"
exit $fail
