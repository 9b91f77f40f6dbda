#!/bin/sh
# Gmsh files other tools read, and tissue names from the image to the mesh.
#  1. The knee atlas (its knee_atlas.ctbl names the tissues) meshed at --delta 2 into MSH 4.1:
#     with Gmsh's Python API the physical volume names are the table's names of the labels
#     present (label_<v> for a label the table does not name), every volume's getBoundary is
#     non-empty and made of interface surfaces "interface_<a>_<b>" that hold its label, signed
#     + where their normals leave it (from a to b), the element and node counts equal i2m's
#     report; meshio reads the same counts and per-label tets; i2m-check finds it valid (the
#     fidelity check on this image takes a minute: it is done on the small image below).
#  2. A small image with a colour table written here, meshed into MSH 4.1 and 2.2, binary and
#     ASCII: Gmsh and meshio read each with the report's counts, the same per-label tets and
#     the table's names; i2m-check passes every guarantee (check_guarantees).
#  3. 3D Slicer segmentations (.seg.nrrd) of one and of two layers written here: i2m-info
#     prints the segment names, and they come out as the mesh's physical names.
#  4. --msh-format and --ascii are refused for other outputs and for unknown versions;
#     I2M_MSH_ASCII=1 still gives ASCII.
set -eu
. tests/scripts/guarantees.sh
if ! "$PY" -c "import gmsh, meshio, numpy" 2>/dev/null; then
  echo "SKIP: the Python modules gmsh, meshio or numpy are missing"
  exit 0
fi
T="$TMP"
fail() { echo "FAIL: $*"; exit 1; }

# checks.py MESH REPORT CTBL [VERSION]: the checks of parts 1 and 2 on one file
cat >"$T/checks.py" <<'PYEOF'
import sys, json, collections, warnings
import numpy as np
import gmsh, meshio
warnings.simplefilter("ignore")
path, report, ctbl = sys.argv[1:4]
version = sys.argv[4] if len(sys.argv) > 4 else "4.1"
fails = []

def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what)
    if not cond:
        fails.append(what)

names = {}
for line in open(ctbl):
    w = line.split()
    if w and not w[0].startswith("#"):
        names[int(w[0])] = " ".join(w[1:-4])
counts = json.load(open(report))["counts"]

gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
gmsh.open(path)
vol_groups = gmsh.model.getPhysicalGroups(3)
sur_groups = gmsh.model.getPhysicalGroups(2)
got = {t: gmsh.model.getPhysicalName(3, t) for _, t in vol_groups}
want = {t: names.get(t, f"label_{t}").replace('"', "'") for t in got}  # (no quote inside a name)
check(got == want, f"{path}: {len(got)} physical volume names are the table's ({sum(t in names for t in got)} named)")
check(sum(t in names for t in got) >= 1, f"{path}: some names come from the table")
pair = {}
for _, t in sur_groups:
    n = gmsh.model.getPhysicalName(2, t)
    a, b = n.split("_")[1:]
    pair[t] = (int(a), int(b))
check(len(pair) > 0 and all(gmsh.model.getPhysicalName(2, t).startswith("interface_") for t in pair),
      f"{path}: {len(pair)} interface surfaces named interface_<a>_<b>")
ntet = ntri = 0
bad_boundaries = 0
tets_per_label = collections.Counter()
for dim, tag in gmsh.model.getEntities(3):
    label = gmsh.model.getPhysicalGroupsForEntity(dim, tag)[0]
    types, elems, _ = gmsh.model.mesh.getElements(dim, tag)
    n = sum(len(e) for e in elems)
    ntet += n
    tets_per_label[label] += n
    if version == "4.1":  # (MSH 2.2 has no entities, so Gmsh knows no boundaries)
        bnd = gmsh.model.getBoundary([(dim, tag)], combined=False, oriented=True)
        ok = len(bnd) > 0
        for _, s in bnd:
            ab = pair[gmsh.model.getPhysicalGroupsForEntity(2, abs(s))[0]]
            ok = ok and label in ab and (s > 0) == (label == ab[1])  # (normals from the higher label to the lower)
        if not ok:
            bad_boundaries += 1
            print(f"     volume {tag} (label {label}): boundary {bnd}")
for dim, tag in gmsh.model.getEntities(2):
    ntri += sum(len(e) for e in gmsh.model.mesh.getElements(dim, tag)[1])
if version == "4.1":
    check(bad_boundaries == 0, f"{path}: every volume's boundary: interface surfaces of its label, signed")
nodes = len(gmsh.model.mesh.getNodes()[0])
check((nodes, ntet, ntri) == (counts["vertices"], counts["tetrahedra"], counts["interface_triangles"]),
      f"{path}: gmsh reads {nodes} nodes, {ntet} tets, {ntri} triangles (report: {counts['vertices']}, "
      f"{counts['tetrahedra']}, {counts['interface_triangles']})")
gmsh.finalize()

m = meshio.read(path)
mt = sum(len(c.data) for c in m.cells if c.type == "tetra")
mf = sum(len(c.data) for c in m.cells if c.type == "triangle")
check((len(m.points), mt, mf) == (nodes, ntet, ntri), f"{path}: meshio reads the same counts")
phys = collections.Counter()
for c, v in zip(m.cells, m.cell_data["gmsh:physical"]):
    if c.type == "tetra":
        phys.update(int(x) for x in v)
check(phys == tets_per_label, f"{path}: meshio's gmsh:physical of the tets match Gmsh's groups")
fd = {n: int(v[0]) for n, v in m.field_data.items() if int(v[1]) == 3}
check(fd == {n: t for t, n in got.items()}, f"{path}: meshio's field_data names the same volumes")
print("FAILURES" if fails else "all checks passed")
sys.exit(1 if fails else 0)
PYEOF

# ---- 1. the knee atlas
echo "== knee atlas, --delta 2, MSH 4.1"
"$BIN/i2m" "$DATA/knee_atlas.nrrd" --delta 2 -o "$T/knee.msh" --report "$T/knee.json" --quiet || fail "i2m on the knee"
"$PY" "$T/checks.py" "$T/knee.msh" "$T/knee.json" "$DATA/knee_atlas.ctbl" || fail "knee.msh"
"$BIN/i2m-check" "$T/knee.msh" >"$T/knee.check" || { tail -5 "$T/knee.check"; fail "i2m-check knee.msh"; }

# ---- 2. a small image with a colour table, four kinds of file
echo "== small image: MSH 4.1 and 2.2, binary and ASCII"
"$BIN/i2m-mkimage" --shape shells --dims 24,20,16 --labels 2,5,9 -o "$T/shells.nrrd" >/dev/null
printf '# Color table file\n2 outer shell 200 10 10 255\n5 "middle" 10 200 10 255\n7 absent 1 1 1 255\n' >"$T/shells.ctbl"
"$BIN/i2m-info" "$T/shells.nrrd" | grep -q "outer shell" || fail "i2m-info shows no table name"
for v in "4.1" "4.1 --ascii" "2.2" "2.2 --ascii"; do
  f="$T/shells_$(echo "$v" | tr -d ' .-').msh"
  # shellcheck disable=SC2086
  "$BIN/i2m" "$T/shells.nrrd" -o "$f" --report "$T/shells.json" --msh-format $v --quiet || fail "i2m --msh-format $v"
  case $v in *ascii) head -2 "$f" | grep -q " 0 8" || fail "$f is not ASCII" ;; *) head -2 "$f" | grep -q " 1 8" || fail "$f is not binary" ;; esac
  "$PY" "$T/checks.py" "$f" "$T/shells.json" "$T/shells.ctbl" "${v% --ascii}" || fail "$f"
  check_guarantees "$f" "$T/shells.nrrd" "$T/shells.json" >"$T/check.log" || { tail -5 "$T/check.log"; fail "i2m-check $f"; }
  echo "ok   i2m-check passes $f"
done

# ---- 3. 3D Slicer segmentations
echo "== 3D Slicer segmentations"
"$PY" - "$T" <<'PYEOF'
import sys
import numpy as np
d = sys.argv[1]
n = 14
z, y, x = np.mgrid[0:n, 0:n, 0:n]
def ball(cx, r):
    return (x - cx) ** 2 + (y - 7) ** 2 + (z - 7) ** 2 < r * r
def write(name, data, layers, segs):
    hdr = ["NRRD0004", "type: unsigned char", "encoding: raw", "space: left-posterior-superior"]
    if layers > 1:
        hdr += ["dimension: 4", f"sizes: {layers} {n} {n} {n}", "kinds: list domain domain domain",
                "space directions: none (0.7,0,0) (0,0.7,0) (0,0,0.7)"]
    else:
        hdr += ["dimension: 3", f"sizes: {n} {n} {n}", "space directions: (0.7,0,0) (0,0.7,0) (0,0,0.7)"]
    hdr += ["space origin: (-4,2,10)", "Segmentation_MasterRepresentation:=Binary labelmap"]
    for i, (nm, value, layer) in enumerate(segs):
        hdr += [f"Segment{i}_ID:=Segment_{i + 1}", f"Segment{i}_Name:={nm}", f"Segment{i}_LabelValue:={value}",
                f"Segment{i}_Layer:={layer}", f"Segment{i}_Color:=0.5 0.5 0.5"]
    with open(f"{d}/{name}", "wb") as f:
        f.write(("\n".join(hdr) + "\n\n").encode())
        f.write(np.ascontiguousarray(data, dtype=np.uint8).tobytes())
one = np.zeros((n, n, n), np.uint8)
one[ball(5, 4)] = 3
one[ball(10, 3)] = 6
write("one.seg.nrrd", one, 1, [("left kidney", 3, 0), ("right kidney", 6, 0)])
two = np.zeros((n, n, n, 2), np.uint8)  # (layer fastest)
two[..., 0][ball(6, 5)] = 1
two[..., 1][ball(9, 3)] = 1
write("two.seg.nrrd", two, 2, [("liver", 1, 0), ("tumour", 1, 1)])
PYEOF
"$BIN/i2m-info" "$T/one.seg.nrrd" >"$T/one.info"
grep -q "left kidney" "$T/one.info" && grep -q "right kidney" "$T/one.info" || fail "i2m-info one.seg.nrrd: $(cat "$T/one.info")"
"$BIN/i2m-info" "$T/two.seg.nrrd" >"$T/two.info" 2>"$T/two.err"
grep -q "liver" "$T/two.info" && grep -q "tumour" "$T/two.info" || fail "i2m-info two.seg.nrrd: $(cat "$T/two.info")"
grep -q "voxels lie in segments of several layers" "$T/two.err" || fail "no overlap warning: $(cat "$T/two.err")"
"$BIN/i2m" "$T/one.seg.nrrd" -o "$T/one.msh" --quiet || fail "i2m one.seg.nrrd"
"$BIN/i2m" "$T/two.seg.nrrd" -o "$T/two.msh" --quiet 2>/dev/null || fail "i2m two.seg.nrrd"
"$PY" - "$T" <<'PYEOF' || fail "segment names in the meshes"
import sys, gmsh
d = sys.argv[1]
gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
ok = True
# one layer: the values kept; two layers sharing value 1: renumbered in segment order
for f, want in [("one.msh", {3: "left kidney", 6: "right kidney"}), ("two.msh", {1: "liver", 2: "tumour"})]:
    gmsh.open(f"{d}/{f}")
    got = {t: gmsh.model.getPhysicalName(3, t) for _, t in gmsh.model.getPhysicalGroups(3)}
    print(("ok   " if got == want else "FAIL ") + f"{f}: physical volumes {got}")
    ok = ok and got == want
gmsh.finalize()
sys.exit(0 if ok else 1)
PYEOF

# ---- 4. options
echo "== options"
set +e
"$BIN/i2m" "$T/shells.nrrd" -o "$T/x.vtu" --ascii 2>"$T/err"; st=$?
[ $st -eq 2 ] && [ "$(wc -l <"$T/err")" -eq 1 ] && grep -q "Gmsh output only" "$T/err" || fail "--ascii with .vtu: status $st, $(cat "$T/err")"
"$BIN/i2m" "$T/shells.nrrd" -o "$T/x.mesh" --msh-format 2.2 2>"$T/err"; st=$?
[ $st -eq 2 ] && grep -q "Gmsh output only" "$T/err" || fail "--msh-format with .mesh: status $st"
"$BIN/i2m" "$T/shells.nrrd" -o "$T/x.msh" --msh-format 3.0 2>"$T/err"; st=$?
[ $st -eq 2 ] && grep -q "4.1 or 2.2" "$T/err" || fail "--msh-format 3.0: status $st"
set -e
[ ! -e "$T/x.vtu" ] && [ ! -e "$T/x.mesh" ] && [ ! -e "$T/x.msh" ] || fail "a refused run wrote a file"
I2M_MSH_ASCII=1 "$BIN/i2m" "$T/shells.nrrd" -o "$T/env.msh" --quiet
head -2 "$T/env.msh" | grep -q "^4.1 0 8" || fail "I2M_MSH_ASCII=1 did not give ASCII"
echo "ok   options"
echo "all Gmsh checks passed"
