#!/bin/sh
# The mesh writers' files open in meshio (an independent reader): VTU, Medit, Gmsh binary
# and ASCII.  How it works: the CUnit program test_io_writers, run with I2M_SAMPLE_OUT=DIR,
# writes DIR/sample.{vtu,mesh,msh}, DIR/sample_ascii.msh and DIR/sample.expect (point,
# tetra and triangle counts and the material of every tetrahedron in the writer's order);
# this script reads each file with $PYTHON + meshio and compares.  The program is taken
# from $I2M_TEST_BIN (default build/release/tests), built by `make unit-tests` if missing.
# Run from the project root by tests/run_scripts.sh ($I2M_TMP is a private scratch dir).
set -eu
TB="${I2M_TEST_BIN:-build/release/tests}"
PY="${PYTHON:-/usr/bin/python3}"
[ -x "$TB/test_io_writers" ] || make --no-print-directory unit-tests >/dev/null
out="$I2M_TMP/meshio"
mkdir -p "$out"
I2M_SAMPLE_OUT="$out" "$TB/test_io_writers"
"$PY" - "$out" <<'PYEOF'
import sys, collections, warnings
import numpy as np
import meshio
warnings.simplefilter("ignore")
d = sys.argv[1]
exp = {}
for line in open(f"{d}/sample.expect"):
    k, *v = line.split()
    exp[k] = [int(x) for x in v]
npts, ntet, ntri = exp["points"][0], exp["tetra"][0], exp["triangle"][0]
mats = collections.Counter(exp["materials"])
fails = []

def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what)
    if not cond:
        fails.append(what)

def cells(m, kind, key):
    data = [c.data for c in m.cells if c.type == kind]
    vals = [v for c, v in zip(m.cells, m.cell_data.get(key, [[]] * len(m.cells))) if c.type == kind]
    n = sum(len(x) for x in data)
    return n, (np.concatenate(vals) if vals else np.array([], int))

def tet_volumes_positive(m):
    p = m.points
    ok = True
    for c in m.cells:
        if c.type != "tetra":
            continue
        a, b, cc, dd = (p[c.data[:, i]] for i in range(4))
        v = np.einsum("ij,ij->i", b - a, np.cross(cc - a, dd - a))
        ok = ok and bool(np.all(v > 0))
    return ok

for name, key, has_tri in [("sample.vtu", "material", False), ("sample.mesh", "medit:ref", True),
                           ("sample.msh", "gmsh:physical", True),
                           ("sample_ascii.msh", "gmsh:physical", True)]:
    m = meshio.read(f"{d}/{name}")
    check(len(m.points) == npts, f"{name}: {len(m.points)} points, expected {npts}")
    n, v = cells(m, "tetra", key)
    check(n == ntet, f"{name}: {n} tetra, expected {ntet}")
    check(collections.Counter(int(x) for x in v) == mats, f"{name}: tetra {key} values match")
    check(tet_volumes_positive(m), f"{name}: every tetra has a positive volume")
    n, v = cells(m, "triangle", key)
    check(n == (ntri if has_tri else 0), f"{name}: {n} triangles, expected {ntri if has_tri else 0}")
    if name.endswith(".msh"):
        names = {n: t for n, t in m.field_data.items()}
        ok = all(f"label_{k}" in names and names[f"label_{k}"][0] == k and names[f"label_{k}"][1] == 3
                 for k in mats)
        check(ok, f"{name}: physical volume names label_<v> with tag v")
        check(any(n.startswith("interface_") for n in names), f"{name}: interface physical names")
    if name == "sample.mesh":
        txt = open(f"{d}/{name}").read()
        check("# i2m interface 1 = labels 0 5" in txt, f"{name}: interface comment block")
print("FAILURES" if fails else "all meshio checks passed")
sys.exit(1 if fails else 0)
PYEOF
