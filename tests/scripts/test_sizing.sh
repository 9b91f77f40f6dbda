#!/bin/sh
# --region and --size-label change element sizes where asked and only there: compared with a
# default run, the mean edge length of the tets inside the region (of the label) shrinks to
# at most 60%, and that of the tets far from the region (of the other labels) changes by at
# most 15%.  Both meshes must be valid with the ratio bound (the region's own bound inside).
set -eu
BIN=${I2M_BIN:-bin}
DATA=${I2M_DATA:-../shared/data}
TMP=${I2M_TMP:-$(mktemp -d)}
PY=${PYTHON:-/usr/bin/python3}
IMG=$DATA/spine_verse009.nii.gz
"$BIN/i2m" "$IMG" -o "$TMP/base.vtu" --quiet
# a world box around the middle of the image (spine: LPS world box from i2m-info)
box=$("$BIN/i2m-info" "$IMG" --json | "$PY" -c '
import json, sys
d = json.load(sys.stdin)
import itertools
n, s, o, D = d["dims"], d["spacing"], d["origin"], d["direction"]
pts = []
for c in itertools.product(*[(-0.5, n[a] - 0.5) for a in range(3)]):
    g = [c[a] * s[a] for a in range(3)]
    pts.append([o[r] + sum(D[r][a] * g[a] for a in range(3)) for r in range(3)])
lo = [min(p[a] for p in pts) for a in range(3)]; hi = [max(p[a] for p in pts) for a in range(3)]
mid = [(lo[a] + hi[a]) / 2 for a in range(3)]; ext = [(hi[a] - lo[a]) for a in range(3)]
print(",".join("%g" % (mid[a] - ext[a] / 6) for a in range(3)) + "," + ",".join("%g" % (mid[a] + ext[a] / 6) for a in range(3)))')
"$BIN/i2m" "$IMG" -o "$TMP/region.vtu" --region "$box:0.7:2.5" --quiet
"$BIN/i2m" "$IMG" -o "$TMP/label.vtu" --size-label 17=0.7 --quiet
"$BIN/i2m-check" "$TMP/region.vtu" --max-ratio 2.5 >/dev/null
"$BIN/i2m-check" "$TMP/label.vtu" --max-ratio 2 >/dev/null
"$PY" - "$TMP" "$box" <<'PY'
import sys, meshio, numpy as np
tmp, box = sys.argv[1], [float(x) for x in sys.argv[2].split(",")]
lo, hi = np.array(box[:3]), np.array(box[3:])
def load(name):
    m = meshio.read(f"{tmp}/{name}.vtu")
    t = m.cells_dict["tetra"]; p = m.points
    e = [(0,1),(0,2),(0,3),(1,2),(1,3),(2,3)]
    L = np.mean([np.linalg.norm(p[t[:, a]] - p[t[:, b]], axis=1) for a, b in e], axis=0)
    return p[t].mean(axis=1), L, m.cell_data["material"][0]
def dist_to_box(c):
    d = np.maximum(np.maximum(lo - c, c - hi), 0)
    return np.linalg.norm(d, axis=1)
ok = True
def compare(what, base, new, shrink):
    global ok
    r = new / base
    good = r <= 0.6 if shrink else abs(r - 1) <= 0.15
    ok &= good
    print(f"{'ok  ' if good else 'FAIL'} {what}: mean edge {base:.3f} -> {new:.3f} mm (x{r:.2f})")
cb, Lb, Mb = load("base"); cr, Lr, Mr = load("region"); cl, Ll, Ml = load("label")
compare("region, tets inside the box", Lb[dist_to_box(cb) == 0].mean(), Lr[dist_to_box(cr) == 0].mean(), True)
compare("region, tets 20 mm or more away", Lb[dist_to_box(cb) > 20].mean(), Lr[dist_to_box(cr) > 20].mean(), False)
compare("size-label 17, its tets", Lb[Mb == 17].mean(), Ll[Ml == 17].mean(), True)
far = [9, 10, 11, 22, 23, 24]
compare("size-label 17, labels far from it", Lb[np.isin(Mb, far)].mean(), Ll[np.isin(Ml, far)].mean(), False)
sys.exit(0 if ok else 1)
PY
