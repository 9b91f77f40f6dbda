#!/bin/sh
# Interface triangles point from the higher label to the lower (the background 0 ranking below
# every tissue): out of the meshed domain on the outer boundary, the Medit / mmg / Gmsh
# convention.  The liver at --delta 4, written as Medit and Gmsh, read back with meshio (an
# independent reader): every outer-boundary triangle's normal points away from its one tet,
# every triangle between two tissues points into the tet of the lower label, and the closed
# outer surface encloses a positive signed volume (sum of det(a,b,c)/6) equal to the tets'.
# The same on a synthetic image with a negative label (the background still ranks lowest),
# and on a mesh stitched from 2 MPI ranks when mpirun is there (with its Medit side file,
# written by rank 0: medit_side_check.py).
# i2m-check reports the orientation: the file as written is "outward"; with every triangle
# flipped it is "inward" and still valid; with half of them flipped it is "mixed": invalid
# (exit 1, the error mixed_triangle_orientation).
set -eu
B="${I2M_BIN:-bin}"
D="${I2M_DATA:-../shared/data}"
PY="${PYTHON:-/usr/bin/python3}"
T="$I2M_TMP/orient"
mkdir -p "$T"
fail=0
bad() { echo "FAIL $*"; fail=1; }

# meshio_check FILE: the orientation properties above, read by meshio
meshio_check() {
  "$PY" - "$1" <<'EOF'
import sys, warnings
import numpy as np
import meshio
warnings.simplefilter("ignore")
path = sys.argv[1]
m = meshio.read(path)
key = "medit:ref" if path.endswith(".mesh") else "gmsh:physical"
P = m.points
tet = np.concatenate([c.data for c in m.cells if c.type == "tetra"])
lab = np.concatenate([d for c, d in zip(m.cells, m.cell_data[key]) if c.type == "tetra"])
tri = np.concatenate([c.data for c in m.cells if c.type == "triangle"])
def keys(ids):  # a sorted vertex triple as one integer
    k = np.sort(ids, axis=1).astype(np.int64)
    return (k[:, 0] << 42) | (k[:, 1] << 21) | k[:, 2]
assert len(P) < 1 << 21
FACES = ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1))  # face i of a tet is opposite vertex i
fkey = np.concatenate([keys(tet[:, f]) for f in FACES])
ftet = np.tile(np.arange(len(tet)), 4)
fopp = np.concatenate([tet[:, i] for i in range(4)])
order = np.argsort(fkey, kind="stable")
fkey, ftet, fopp = fkey[order], ftet[order], fopp[order]
tkey = keys(tri)
lo, hi = np.searchsorted(fkey, tkey, "left"), np.searchsorted(fkey, tkey, "right")
assert np.all((hi - lo == 1) | (hi - lo == 2)), "a file triangle that is not a face of one or two tets"
a, b, c = P[tri[:, 0]], P[tri[:, 1]], P[tri[:, 2]]
normal = np.cross(b - a, c - a)
def into(j, rows):  # does triangle rows[i]'s normal point into the tet at face slot j[i]?
    return np.einsum("ij,ij->i", normal[rows], P[fopp[j]] - a[rows]) > 0
every = np.arange(len(tri))
outer_mask = hi - lo == 1
outer = int(outer_mask.sum())
in0 = into(lo, every)
outer_wrong = int((in0 & outer_mask).sum())
enclosed = float(np.einsum("ij,ij->i", a, np.cross(b, c))[outer_mask].sum()) / 6
two = ~outer_mask
j0, j1 = lo[two], lo[two] + 1
i0, i1 = in0[two], into(j1, two)
lab0, lab1 = lab[ftet[j0]], lab[ftet[j1]]
lab_in = np.where(i0, lab0, lab1)    # the label the normal points into
lab_out = np.where(i0, lab1, lab0)
def ranks_below(x, y):  # background 0 below every tissue, tissues by value
    return (x != y) & ((x == 0) | ((y != 0) & (x < y)))
inner_wrong = int(((i0 == i1) | ~ranks_below(lab_in, lab_out)).sum())
x = P[tet]
volume = float(np.einsum("ij,ij->i", x[:, 1] - x[:, 0], np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 0])).sum()) / 6
print(f"{path}: {len(tri)} triangles, {outer} on the outer boundary ({outer_wrong} pointing into their tet), "
      f"{inner_wrong} between tissues pointing the wrong way; enclosed {enclosed:.6g}, tets {volume:.6g}")
ok = outer > 0 and outer_wrong == 0 and inner_wrong == 0 and enclosed > 0 and abs(enclosed - volume) <= 1e-6 * volume
sys.exit(0 if ok else 1)
EOF
}

# ck_expect FILE CODE ORIENTATION [ERROR]: i2m-check's exit code and reported orientation
ck_expect() {
  set +e
  "$B/i2m-check" "$1" --json > "$T/ck.json" 2> "$T/ck.err"
  code=$?
  "$B/i2m-check" "$1" > "$T/ck.txt" 2>&1
  set -e
  [ "$code" = "$2" ] || { bad "i2m-check $1: exit $code, expected $2 ($(head -c 200 "$T/ck.err"))"; return; }
  grep -q "file triangle orientation: $3 " "$T/ck.txt" || bad "i2m-check $1: the text report does not say '$3'"
  if "$PY" -c "import json, sys; v = json.load(open('$T/ck.json'))['validity']
assert v['triangle_orientation'] == '$3', v['triangle_orientation']
assert v['file_triangles_outward'] + v['file_triangles_inward'] == v['file_triangles']
assert ('mixed_triangle_orientation' in v['errors']) == ('$3' == 'mixed')" 2> "$T/py.err"; then
    echo "ok   i2m-check $(basename "$1"): exit $code, $3"
  else
    bad "i2m-check $1 JSON: $(tail -n 1 "$T/py.err")"
  fi
}

# flip_medit IN OUT EVERY: swaps two vertices of every EVERY-th triangle of a Medit file
flip_medit() {
  awk -v every="$3" '
    /^Triangles/ { sec = 1; print; next }
    sec == 1 { sec = 2; print; next }
    sec == 2 && NF == 4 { if (k++ % every == 0) { x = $1; $1 = $2; $2 = x }; print; next }
    { sec = 0; print }' "$1" > "$2"
}

for f in liver.mesh liver.msh; do
  "$B/i2m" "$D/liver.inr.gz" -o "$T/$f" --delta 4 --quiet || bad "i2m liver -> $f"
  if meshio_check "$T/$f"; then echo "ok   $f: triangles point out of the domain, from the higher label to the lower"
  else bad "$f: orientation (meshio)"; fi
  ck_expect "$T/$f" 0 outward
done

flip_medit "$T/liver.mesh" "$T/inward.mesh" 1
flip_medit "$T/liver.mesh" "$T/mixed.mesh" 2
cmp -s "$T/liver.mesh" "$T/inward.mesh" && bad "flip_medit changed nothing"
ck_expect "$T/inward.mesh" 0 inward
ck_expect "$T/mixed.mesh" 1 mixed
if meshio_check "$T/inward.mesh" > /dev/null; then bad "the meshio check accepts a flipped mesh"
else echo "ok   the meshio check fails on the flipped mesh"; fi

# a negative label: the outer boundary still points out (the background ranks lowest)
"$B/i2m-mkimage" --shape shells --dims 24,24,24 --type int16 --labels -5,3,7 -o "$T/neg.nrrd" > /dev/null
"$B/i2m" "$T/neg.nrrd" -o "$T/neg.mesh" --quiet || bad "i2m neg.nrrd"
if meshio_check "$T/neg.mesh"; then echo "ok   neg.mesh: a negative label, triangles point out"
else bad "neg.mesh: orientation (meshio)"; fi
ck_expect "$T/neg.mesh" 0 outward

# a Medit mesh stitched on rank 0 from 2 ranks' pieces
if command -v mpirun > /dev/null 2>&1; then
  export OMPI_MCA_mpi_yield_when_idle=1 OMPI_MCA_rmaps_base_oversubscribe=1
  MPIRUN="mpirun --oversubscribe --bind-to none"
  [ "$(id -u)" = 0 ] && MPIRUN="$MPIRUN --allow-run-as-root"
  mpirun --version 2>/dev/null | grep -qi "open mpi" || MPIRUN="mpirun"
  "$B/i2m-mkimage" --shape shells --dims 40,40,40 -o "$T/shells.nrrd" > /dev/null
  if OMP_NUM_THREADS=1 timeout 120 $MPIRUN -np 2 "$B/i2m" "$T/shells.nrrd" -o "$T/mpi.mesh" --depth 1 --quiet; then
    if meshio_check "$T/mpi.mesh"; then echo "ok   mpi.mesh (2 ranks): triangles point out"
    else bad "mpi.mesh: orientation (meshio)"; fi
    ck_expect "$T/mpi.mesh" 0 outward
    if "$PY" "$(dirname "$0")/medit_side_check.py" "$T/mpi.mesh"; then echo "ok   mpi.mesh.json (written by rank 0)"
    else bad "mpi.mesh.json"; fi
  else
    bad "mpirun -np 2 i2m"
  fi
else
  echo "SKIP the MPI part: no mpirun"
fi

[ $fail = 0 ] && echo "orientation: all passed"
exit $fail
