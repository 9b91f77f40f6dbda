#!/bin/sh
# Compressed VTU and its interfaces file, read by other tools.  The liver at --delta 4 meshed
# to l.vtu (zlib by default) and r.vtu (--vtu-raw):
#   VTK's own XML reader (vtkXMLUnstructuredGridReader) reads l.vtu, l.interfaces.vtu and
#   r.vtu: point, tet and triangle counts equal i2m's --report, the materials are the report's
#   labels, every triangle's (label_a, label_b) has a < b and both are materials or 0, every
#   material has interface triangles; the header says vtkZLibDataCompressor (r.vtu: nothing);
#   meshio reads l.vtu with the same counts and materials;
#   a mesh written by meshio (its VTU writer: inline base64, zlib by default, UInt32 and UInt64
#   headers) passes bin/i2m-check with the tet count and per-label volumes of i2m's own file.
# p.pvtu and p.interfaces.pvtu (one process) read by VTK's parallel reader with the report's
# counts.  Python parts skip with one line when vtk or meshio is missing.
set -u
BIN="${I2M_BIN:-bin}"
PY="${PYTHON:-/usr/bin/python3}"
DATA="${I2M_DATA:-../shared/data}"
T="$I2M_TMP/vtuz"
mkdir -p "$T"
fail=0
say() { printf '%s\n' "$*"; }
bad() { say "FAIL: $*"; fail=1; }
LIVER="$DATA/liver.inr.gz"

"$BIN/i2m" "$LIVER" --delta 4 -o "$T/l.vtu" --report "$T/l.json" --quiet || { say "FAIL: i2m -o l.vtu"; exit 1; }
"$BIN/i2m" "$LIVER" --delta 4 -o "$T/r.vtu" --report "$T/r.json" --quiet --vtu-raw || { say "FAIL: i2m --vtu-raw"; exit 1; }
for f in l.interfaces.vtu r.interfaces.vtu; do [ -s "$T/$f" ] || bad "no $f"; done
head -c 400 "$T/l.vtu" | grep -q 'compressor="vtkZLibDataCompressor"' || bad "l.vtu: no vtkZLibDataCompressor in its header"
head -c 400 "$T/r.vtu" | grep -q 'compressor=' && bad "r.vtu (--vtu-raw): compressed"
[ "$(wc -c < "$T/l.vtu")" -lt "$(wc -c < "$T/r.vtu")" ] || bad "l.vtu is not smaller than r.vtu"

# a .pvtu (one process: one piece, and one interfaces piece)
"$BIN/i2m" "$LIVER" --delta 4 -o "$T/p.pvtu" --report "$T/p.json" --quiet || bad "i2m -o p.pvtu"
for f in p_0.vtu p.interfaces.pvtu p_0.interfaces.vtu; do [ -s "$T/$f" ] || bad "no $f"; done

# VTK: counts and labels of each file against its report
if "$PY" -c 'import vtk' 2> /dev/null; then
  "$PY" - "$T" <<'EOF' || bad "VTK's reader: see above"
import json, sys
import vtk
from vtk.util.numpy_support import vtk_to_numpy
d = sys.argv[1]
fails = []

def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what)
    if not cond:
        fails.append(what)

def read(path, parallel=False):
    r = vtk.vtkXMLPUnstructuredGridReader() if parallel else vtk.vtkXMLUnstructuredGridReader()
    errors = []
    r.AddObserver("ErrorEvent", lambda obj, ev: errors.append(ev))
    r.AddObserver("WarningEvent", lambda obj, ev: errors.append(ev))
    r.SetFileName(path)
    r.Update()
    check(not errors, f"{path.rsplit('/', 1)[-1]}: read without errors or warnings")
    return r.GetOutput()

def cell_array(g, name):
    a = g.GetCellData().GetArray(name)
    return vtk_to_numpy(a) if a is not None else None

def check_pair(mesh, ifaces, rep, tag, parallel=False):
    c = json.load(open(f"{d}/{rep}"))["counts"]
    labels = {l["label"] for l in json.load(open(f"{d}/{rep}"))["labels"] if l["tets"] > 0}
    g, s = read(f"{d}/{mesh}", parallel), read(f"{d}/{ifaces}", parallel)
    if not parallel:  # (pieces repeat their seam vertices)
        check(g.GetNumberOfPoints() == c["vertices"], f"{tag}: {g.GetNumberOfPoints()} points, report {c['vertices']}")
    check(g.GetNumberOfCells() == c["tetrahedra"], f"{tag}: {g.GetNumberOfCells()} cells, report {c['tetrahedra']}")
    types = set(vtk_to_numpy(g.GetCellTypesArray()).tolist())
    check(types == {10}, f"{tag}: every cell a tetrahedron ({types})")
    mat = cell_array(g, "material")
    check(mat is not None and set(mat.tolist()) == labels, f"{tag}: materials = the report's labels {sorted(labels)}")
    n = s.GetNumberOfCells()
    check(n == c["interface_triangles"], f"{tag} interfaces: {n} triangles, report {c['interface_triangles']}")
    if n:
        check(set(vtk_to_numpy(s.GetCellTypesArray()).tolist()) == {5}, f"{tag} interfaces: every cell a triangle")
    a, b = cell_array(s, "label_a"), cell_array(s, "label_b")
    ok = a is not None and b is not None and bool((a < b).all())
    check(ok, f"{tag} interfaces: label_a < label_b on every triangle")
    if ok:
        check(set(a.tolist()) | set(b.tolist()) <= labels | {0}, f"{tag} interfaces: labels are materials or 0")
        check(set(b.tolist()) == labels, f"{tag} interfaces: every material bounds some triangle")

check_pair("l.vtu", "l.interfaces.vtu", "l.json", "l.vtu (zlib)")
check_pair("r.vtu", "r.interfaces.vtu", "r.json", "r.vtu (raw)")
check_pair("p.pvtu", "p.interfaces.pvtu", "p.json", "p.pvtu (pieces)", parallel=True)
print("FAILURES" if fails else "all VTK checks passed")
sys.exit(1 if fails else 0)
EOF
else
  say "SKIP: VTK checks (python3 vtk module missing)"
fi

# meshio: reads i2m's compressed file; writes one that i2m-check must judge like i2m's own
if "$PY" -c 'import meshio' 2> /dev/null; then
  "$PY" - "$T" <<'EOF' || bad "meshio: see above"
import collections, json, sys, warnings
import meshio
warnings.simplefilter("ignore")
d = sys.argv[1]
c = json.load(open(f"{d}/l.json"))["counts"]
m = meshio.read(f"{d}/l.vtu")
ntet = sum(len(b.data) for b in m.cells if b.type == "tetra")
ok = len(m.points) == c["vertices"] and ntet == c["tetrahedra"]
print(("ok   " if ok else "FAIL ") + f"meshio reads l.vtu: {len(m.points)} points, {ntet} tetra (report {c['vertices']}, {c['tetrahedra']})")
for ht in ("UInt32", "UInt64"):
    meshio.vtu.write(f"{d}/meshio_{ht}.vtu", m, binary=True, compression="zlib", header_type=ht)
meshio.vtu.write(f"{d}/meshio_b64.vtu", m, binary=True, compression=None)
sys.exit(0 if ok else 1)
EOF
  # ck FILE [--image ...]: i2m-check's JSON of $T/FILE
  ck() {
    f=$1
    shift
    "$BIN/i2m-check" "$T/$f" --json "$@" > "$T/$f.json" 2> "$T/$f.err" || bad "i2m-check $f: $(cat "$T/$f.err")"
  }
  # per-label volumes (with the image) for meshio's default (zlib, UInt32); the tet count and
  # the total volume for the other variants
  ck l.vtu --image "$LIVER" --no-distances
  for f in meshio_UInt32.vtu meshio_UInt64.vtu meshio_b64.vtu; do
    grep -q 'compressor="vtkZLibDataCompressor"' "$T/$f" || [ $f = meshio_b64.vtu ] || bad "$f: not compressed by meshio"
    if [ $f = meshio_UInt32.vtu ]; then ck $f --image "$LIVER" --no-distances; else ck $f; fi
    "$PY" - "$T/l.vtu.json" "$T/$f.json" <<'EOF' || bad "$f: i2m-check figures differ from l.vtu's"
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:])
assert a["valid"] and b["valid"]
assert a["mesh"]["tetrahedra"] == b["mesh"]["tetrahedra"] > 0, (a["mesh"], b["mesh"])
va, vb = a["validity"]["total_volume"], b["validity"]["total_volume"]
assert abs(va - vb) <= 1e-9 * va, (va, vb)
what = f"total volume {vb:.6g}"
if b["fidelity"]:
    va = {l["label"]: l["mesh_volume"] for l in a["fidelity"]["labels"]}
    vb = {l["label"]: l["mesh_volume"] for l in b["fidelity"]["labels"]}
    assert va.keys() == vb.keys() and all(abs(va[k] - vb[k]) <= 1e-9 * max(1.0, abs(va[k])) for k in va), (va, vb)
    what = f"per-label volumes {sorted((k, round(v, 3)) for k, v in vb.items())}"
print(f"ok   {sys.argv[2].rsplit('/', 1)[-1][:-5]}: valid, {b['mesh']['tetrahedra']} tets as l.vtu, {what}")
EOF
  done
else
  say "SKIP: meshio checks (python3 meshio module missing)"
fi

# i2m-check on i2m's raw and compressed files: the same tet count as the report
for f in l r; do
  n=$("$PY" -c 'import json,sys; print(json.load(open(sys.argv[1]))["counts"]["tetrahedra"])' "$T/$f.json")
  "$BIN/i2m-check" "$T/$f.vtu" > "$T/$f.txt" 2>&1 || bad "i2m-check $f.vtu: $(head -n 3 "$T/$f.txt")"
  grep -q "^mesh .*: [0-9]* vertices, $n tetrahedra" "$T/$f.txt" || bad "i2m-check $f.vtu: not $n tetrahedra: $(head -n 1 "$T/$f.txt")"
done

[ $fail = 0 ] && say "test_vtu_compressed: all passed"
exit $fail
