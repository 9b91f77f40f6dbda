#!/bin/sh
# Where the mesh lands: in the image's own world frame (LPS millimetres, the direction matrix
# included), the frame 3D Slicer and ITK use, so the mesh overlays the image there.  On the
# knee atlas (NRRD, y axis flipped: space direction (0,-0.277,0)) meshed coarsely, the
# centroid of every large label's tets must lie within 1 mm of the centroid of that label's
# voxel centres computed here from the NRRD header by hand (origin + directions x index),
# and the flipped axis must not be undone (the two would then differ by tens of mm).
set -eu
. "$(dirname "$0")/guarantees.sh"
img=$DATA/knee_atlas.nrrd
[ -f "$img" ] || { echo "missing $img"; exit 1; }
"$BIN/i2m" "$img" -o "$TMP/k.vtu" --delta 1.5 --quiet
"$PY" - "$img" "$TMP/k.vtu" <<'PYEOF'
import gzip, re, sys
import numpy as np, meshio
path, mesh = sys.argv[1], sys.argv[2]
raw = open(path, "rb").read()
head, body = raw.split(b"\n\n", 1)
h = dict(l.split(": ", 1) for l in head.decode().splitlines()[1:] if ": " in l)
sizes = [int(x) for x in h["sizes"].split()]
dirs = np.array([[float(v) for v in t.split(",")] for t in re.findall(r"\(([^)]*)\)", h["space directions"])])  # rows: axes
origin = np.array([float(v) for v in re.findall(r"\(([^)]*)\)", h["space origin"])[0].split(",")])
assert h["type"] == "short" and h["encoding"] == "gzip" and h["space"] == "left-posterior-superior"
vox = np.frombuffer(gzip.decompress(body), dtype="<i2").reshape(sizes[::-1])  # [k, j, i]
m = meshio.read(mesh)
pts, tets, mat = m.points, m.cells_dict["tetra"], m.cell_data["material"][0]
p = pts[tets]
vol = np.abs(np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))) / 6
cen = p.mean(axis=1)
labels, counts = np.unique(vox, return_counts=True)
worst, n = 0.0, 0
for l, c in zip(labels, counts):
    if l == 0 or c < 200000:
        continue
    k, j, i = np.nonzero(vox == l)
    world = origin + np.stack([i, j, k], axis=1) @ dirs  # index (i, j, k) -> origin + sum_a index_a * dir_a
    want = world.mean(axis=0)
    sel = mat == l
    got = (cen[sel] * vol[sel, None]).sum(axis=0) / vol[sel].sum()
    d = float(np.linalg.norm(got - want))
    worst, n = max(worst, d), n + 1
    if d > 1.0:
        sys.exit("label %d: mesh centroid %s, image centroid %s (%.2f mm apart)" % (l, got, want, d))
assert n >= 5, "too few large labels (%d)" % n
print("ok   knee_atlas.nrrd: %d large labels, mesh and image centroids within %.3f mm (world LPS, flipped y kept)" % (n, worst))
PYEOF

# The mesh frame: an image far from the world's origin is meshed near its own corner and
# shifted back exactly (i2m_image_mesh_shift).  The same shells at the origin, at (1e7, -3e6,
# 5e5) mm and at (-2e9, 1e9, 3e8) mm (0.5 mm voxels: about 2^32 of them from the origin, the
# farthest i2m accepts), one thread (a run is then the same every time: a speculative run's
# tet count varies by about 1%): the far runs say they used the shifted frame, the one at the origin
# does not; every mesh is valid (exact orientations of the written coordinates) and meets
# every guarantee against its own image; moved back to the origin, the far meshes cover the
# same box to 0.04 mm (a tenth of delta) and have the near one's element count and per-label volumes within 1%.
for o in 0,0,0 1e7,-3e6,5e5 -2e9,1e9,3e8; do
  "$BIN/i2m-mkimage" --shape shells --dims 40,36,32 --spacing 0.5,0.5,0.6 --origin "$o" -o "$TMP/far_$o.nrrd" >/dev/null
  "$BIN/i2m" "$TMP/far_$o.nrrd" -o "$TMP/far_$o.vtu" --vtu-raw --threads 1 --report "$TMP/far_$o.json" --verbose \
    2>"$TMP/far_$o.log" >/dev/null || { cat "$TMP/far_$o.log"; exit 1; }
  if grep -q "meshed in a frame shifted by" "$TMP/far_$o.log"; then shifted=yes; else shifted=no; fi
  case $o in 0,0,0) want=no ;; *) want=yes ;; esac
  [ "$shifted" = "$want" ] || { echo "origin $o: shifted frame used: $shifted, expected $want"; exit 1; }
  check_guarantees "$TMP/far_$o.vtu" "$TMP/far_$o.nrrd" "$TMP/far_$o.json" >"$TMP/far_$o.check" 2>&1 ||
    { tail -n 30 "$TMP/far_$o.check"; echo "origin $o: the mesh fails a guarantee"; exit 1; }
done
"$PY" - "$TMP" <<'PYEOF'
import json, sys
import numpy as np, meshio
tmp = sys.argv[1]
def load(o):
    m = meshio.read("%s/far_%s.vtu" % (tmp, o))
    rep = json.load(open("%s/far_%s.json" % (tmp, o)))
    origin = np.array([float(v) for v in o.split(",")])
    vols = {l["label"]: l["volume_mm3"] for l in rep["labels"]}
    return m.points - origin, rep["counts"]["tetrahedra"], vols
p0, n0, v0 = load("0,0,0")
for o in ("1e7,-3e6,5e5", "-2e9,1e9,3e8"):
    p, n, v = load(o)
    box = np.abs(np.concatenate([p.min(0) - p0.min(0), p.max(0) - p0.max(0)])).max()
    assert box < 0.04, "origin %s: the mesh's box moved by %g mm" % (o, box)
    assert abs(n - n0) <= 0.01 * n0, "origin %s: %d tets, %d at the origin" % (o, n, n0)
    for l in v0:
        assert abs(v[l] - v0[l]) <= 0.01 * v0[l], "origin %s, label %d: volume %g, %g at the origin" % (o, l, v[l], v0[l])
    print("ok   shells at %s mm: shifted frame, %d tets (%d at the origin), box within %.1e mm" % (o, n, n0, box))
PYEOF
