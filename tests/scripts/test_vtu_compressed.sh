#!/bin/sh
# Compressed VTU and its interfaces file, read by other tools.  The liver at --delta 4 meshed
# to l.vtu (zlib by default) and r.vtu (--vtu-raw):
#   VTK's own XML reader (vtkXMLUnstructuredGridReader) reads l.vtu, l.interfaces.vtu and
#   r.vtu: point, tet and triangle counts equal i2m's --report, the materials are the report's
#   labels, every triangle's (label_a, label_b) has a < b and both are materials or 0, every
#   material has interface triangles; the header says vtkZLibDataCompressor (r.vtu: nothing);
#   meshio reads l.vtu with the same counts;
#   the mesh written by meshio (inline base64, zlib or not, UInt32 and UInt64 headers) and by
#   VTK's writer (appended raw or base64, inline base64; zlib or not; UInt32 or UInt64) passes
#   bin/i2m-check with the tet count and volumes of i2m's own file.
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
        check(labels <= (set(a.tolist()) | set(b.tolist())), f"{tag} interfaces: every material bounds some triangle")  # (on either side: a label inside others is never label_b)

check_pair("l.vtu", "l.interfaces.vtu", "l.json", "l.vtu (zlib)")
check_pair("r.vtu", "r.interfaces.vtu", "r.json", "r.vtu (raw)")
check_pair("p.pvtu", "p.interfaces.pvtu", "p.json", "p.pvtu (pieces)", parallel=True)
# VTK's own writer, every encoding (its default: appended base64, zlib, UInt32 headers)
g = read(f"{d}/l.vtu")
for mode, enc, comp, ht in [(m, e, c, h) for m in ("appended", "binary") for e in ("b64", "raw")
                            for c in ("zlib", "none") for h in ("UInt32", "UInt64")]:
    if mode == "binary" and enc == "raw":
        continue
    w = vtk.vtkXMLUnstructuredGridWriter()
    w.SetInputData(g)
    w.SetFileName(f"{d}/vtkw_{mode}_{enc}_{comp}_{ht}.vtu")
    w.SetDataModeToAppended() if mode == "appended" else w.SetDataModeToBinary()
    w.SetEncodeAppendedData(enc == "b64")
    w.SetCompressorTypeToZLib() if comp == "zlib" else w.SetCompressorTypeToNone()
    w.SetHeaderTypeToUInt32() if ht == "UInt32" else w.SetHeaderTypeToUInt64()
    check(w.Write() == 1, f"VTK writes vtkw_{mode}_{enc}_{comp}_{ht}.vtu")
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
else
  say "SKIP: meshio checks (python3 meshio module missing)"
fi

# i2m-check judges the files VTK and meshio wrote like i2m's own: valid, the same tets and
# total volume; per-label volumes (with the image) for the defaults of meshio (inline base64,
# zlib, UInt32) and of VTK (appended base64, zlib, UInt32)
# ck FILE [--image ...]: i2m-check's JSON of $T/FILE
ck() {
  f=$1
  shift
  "$BIN/i2m-check" "$T/$f" --json "$@" > "$T/$f.json" 2> "$T/$f.err" || bad "i2m-check $f: $(cat "$T/$f.err")"
}
ck l.vtu --image "$LIVER" --no-distances
others=""
for path in "$T"/meshio_*.vtu "$T"/vtkw_*.vtu; do
  [ -f "$path" ] || continue
  f=$(basename "$path")
  case $f in
    meshio_UInt32.vtu | vtkw_appended_b64_zlib_UInt32.vtu) ck "$f" --image "$LIVER" --no-distances ;;
    *) ck "$f" ;;
  esac
  case $f in *_none_* | meshio_b64.vtu) ;; *) grep -q 'compressor="vtkZLibDataCompressor"' "$path" || bad "$f: not compressed" ;; esac
  [ -s "$T/$f.json" ] && others="$others $T/$f.json"
done
# shellcheck disable=SC2086
[ -z "$others" ] || "$PY" - "$T/l.vtu.json" $others <<'EOF' || bad "i2m-check figures differ from l.vtu's"
import json, sys
a = json.load(open(sys.argv[1]))
fails = 0
for path in sys.argv[2:]:
    b = json.load(open(path))
    name = path.rsplit('/', 1)[-1][:-5]
    va, vb = a["validity"]["total_volume"], b["validity"]["total_volume"]
    ok = a["valid"] and b["valid"] and a["mesh"]["tetrahedra"] == b["mesh"]["tetrahedra"] > 0 and abs(va - vb) <= 1e-9 * va
    what = f"total volume {vb:.6g}"
    if b["fidelity"]:
        la = {l["label"]: l["mesh_volume"] for l in a["fidelity"]["labels"]}
        lb = {l["label"]: l["mesh_volume"] for l in b["fidelity"]["labels"]}
        ok = ok and la.keys() == lb.keys() and all(abs(la[k] - lb[k]) <= 1e-9 * max(1.0, abs(la[k])) for k in la)
        what = f"per-label volumes {sorted((k, round(v, 3)) for k, v in lb.items())}"
    print(("ok   " if ok else "FAIL ") + f"{name}: valid {b['valid']}, {b['mesh']['tetrahedra']} tets (l.vtu {a['mesh']['tetrahedra']}), {what}")
    fails += not ok
sys.exit(1 if fails else 0)
EOF

# i2m-check on i2m's raw and compressed files: the same tet count as the report
for f in l r; do
  n=$("$PY" -c 'import json,sys; print(json.load(open(sys.argv[1]))["counts"]["tetrahedra"])' "$T/$f.json")
  "$BIN/i2m-check" "$T/$f.vtu" > "$T/$f.txt" 2>&1 || bad "i2m-check $f.vtu: $(head -n 3 "$T/$f.txt")"
  grep -q "^mesh .*: [0-9]* vertices, $n tetrahedra" "$T/$f.txt" || bad "i2m-check $f.vtu: not $n tetrahedra: $(head -n 1 "$T/$f.txt")"
done

[ $fail = 0 ] && say "test_vtu_compressed: all passed"
exit $fail
