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
