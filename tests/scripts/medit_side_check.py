"""Checks a Medit mesh written by i2m against its JSON side file NAME.mesh.json.

usage: medit_side_check.py NAME.mesh

The side file must parse; its interface refs must be 1..P, each once, and exactly the refs
the .mesh file's triangles carry (read by meshio, an independent reader, as cell_data
"medit:ref"); the label pair of every ref must be the labels of the tets on the triangle's two
sides (0 on the outer boundary, the lower label first: the background, then by value) for
every triangle with that ref; "tetrahedra" lists exactly the tets' refs; and the .mesh file's
own comment block maps refs to the same pairs.  Exit status 0 when all hold."""
import json
import re
import sys
import warnings

import numpy as np
import meshio

warnings.simplefilter("ignore")
path = sys.argv[1]
side = json.load(open(path + ".json"))
m = meshio.read(path)
tet = np.concatenate([c.data for c in m.cells if c.type == "tetra"])
tet_ref = np.concatenate([d for c, d in zip(m.cells, m.cell_data["medit:ref"]) if c.type == "tetra"])
tri = np.concatenate([c.data for c in m.cells if c.type == "triangle"])
tri_ref = np.concatenate([d for c, d in zip(m.cells, m.cell_data["medit:ref"]) if c.type == "triangle"])
fails = []


def check(cond, what):
    if not cond:
        fails.append(what)


refs = [i["ref"] for i in side["interfaces"]]
pair = {i["ref"]: tuple(i["labels"]) for i in side["interfaces"]}
check(refs == list(range(1, len(refs) + 1)), "interface refs are not 1..P in order")
check(set(int(r) for r in tri_ref) == set(refs), "the triangles' refs differ from the side file's")
check(side["tetrahedra"]["labels"] == sorted(set(int(x) for x in tet_ref)), "tetrahedra labels differ")
check(side["mesh"] == path.rsplit("/", 1)[-1], "the side file names another mesh")


def rank_key(v):  # the background 0 first, then by value
    return (v != 0, v)


# every triangle: the labels of the tets that hold it (0 when one tet: the outer boundary)
def keys(ids):
    k = np.sort(ids, axis=1).astype(np.int64)
    return (k[:, 0] << 42) | (k[:, 1] << 21) | k[:, 2]


assert len(m.points) < 1 << 21
FACES = ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1))
fkey = np.concatenate([keys(tet[:, f]) for f in FACES])
flab = np.tile(tet_ref, 4)
order = np.argsort(fkey, kind="stable")
fkey, flab = fkey[order], flab[order]
tkey = keys(tri)
lo, hi = np.searchsorted(fkey, tkey, "left"), np.searchsorted(fkey, tkey, "right")
check(bool(np.all((hi - lo == 1) | (hi - lo == 2))), "a triangle that is no face of one or two tets")
wrong = 0
for i in range(len(tri)):
    labs = [int(flab[j]) for j in range(lo[i], hi[i])] + ([0] if hi[i] - lo[i] == 1 else [])
    wrong += tuple(sorted(labs, key=rank_key)) != pair.get(int(tri_ref[i]))
check(wrong == 0, f"{wrong} triangles whose tets' labels are not their ref's pair")

comments = {int(a): (int(b), int(c)) for a, b, c in
            re.findall(r"^# i2m interface (\d+) = labels (-?\d+) (-?\d+)$", open(path).read(), re.M)}
check(comments == pair, "the .mesh comment block maps refs to other pairs")

print(f"{path}.json: {len(refs)} interfaces, {len(tri)} triangles, "
      f"{len(side['tetrahedra']['labels'])} tet labels: " + ("; ".join(fails) if fails else "all match"))
sys.exit(1 if fails else 0)
