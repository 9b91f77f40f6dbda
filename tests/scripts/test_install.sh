#!/bin/sh
# i2m as an HPC library: `make install PREFIX=... [DESTDIR=...]` puts the programs, libi2m.a
# and libi2m.so, i2m.h, i2m.pc, the man pages and the Python module in place and `make
# uninstall` takes them away again; the libraries export only i2m_ names; run/example_api.c
# builds through pkg-config (shared, and static with --static) and its mesh follows the
# image (per-label volumes within 5% of the voxels'); every option of --help is in the man
# page; the Python module (ctypes, numpy) meshes an array into a meshio.Mesh whose tet count
# and per-label volumes equal those of bin/i2m on the same image with the same options (both
# --deterministic, a label size and a region).
set -eu
. "$(dirname "$0")/guarantees.sh"
unset MAKEFLAGS MFLAGS MAKEOVERRIDES MAKELEVEL # (a make of its own, not the caller's)
fail=0
ok() { echo "ok   $*"; }
bad() { echo "FAIL $*"; fail=1; }
PFX=$TMP/prefix
make --no-print-directory -s install PREFIX="$PFX" >"$TMP/install.log" 2>&1 || { cat "$TMP/install.log"; bad "make install"; exit 1; }
for f in bin/i2m bin/i2m-check bin/i2m-info lib/libi2m.a lib/libi2m.so include/i2m.h lib/pkgconfig/i2m.pc \
  share/man/man1/i2m.1 share/man/man1/i2m-check.1 share/man/man1/i2m-info.1 share/i2m/python/i2m.py; do
  [ -e "$PFX/$f" ] || bad "make install: no $f"
done
"$PFX/bin/i2m" --version | grep -q "^i2m " && ok "installed i2m runs" || bad "installed i2m does not run"

# only i2m_ names leave the libraries (.gomp_critical_user_*: OpenMP's named critical sections)
leak=$(nm -D --defined-only "$PFX/lib/libi2m.so" | awk '{print $NF}' | grep -v '^i2m_' || true)
[ -z "$leak" ] && ok "libi2m.so exports only i2m_ names ($(nm -D --defined-only "$PFX/lib/libi2m.so" | wc -l))" ||
  bad "libi2m.so exports: $(echo $leak | cut -c1-200)"
leak=$(nm -g --defined-only "$PFX/lib/libi2m.a" | awk 'NF == 3 {print $3}' | grep -v '^i2m_\|^\.gomp_critical_user_i2m_' || true)
[ -z "$leak" ] && ok "libi2m.a: only i2m_ globals" || bad "libi2m.a has globals: $(echo $leak | cut -c1-200)"

# the example through pkg-config, shared and static
export PKG_CONFIG_PATH="$PFX/lib/pkgconfig"
CCX=${CC_EXAMPLE:-cc}
example() { # $1 name: builds and runs the example, checks its volumes
  "$TMP/$1" 32 >"$TMP/$1.out" 2>&1 || { cat "$TMP/$1.out"; bad "$1: the example failed"; return; }
  if awk '/^label/ { v = $6; w = $8; if (v < 0.95 * w || v > 1.05 * w) bad = 1; n++ } END { exit !(n == 2 && !bad) }' "$TMP/$1.out"; then
    ok "$1: $(tr '\n' ';' <"$TMP/$1.out")"
  else
    bad "$1: volumes off: $(cat "$TMP/$1.out")"
  fi
}
# shellcheck disable=SC2046
if $CCX -std=c11 -Wall -Wextra -Werror run/example_api.c $(pkg-config --cflags --libs i2m) -o "$TMP/example_shared"; then
  example example_shared
  ldd "$TMP/example_shared" | grep -q "$PFX/lib/libi2m.so" && ok "the shared example loads $PFX/lib/libi2m.so" ||
    bad "the shared example does not load the installed library"
else bad "the example does not build with pkg-config --cflags --libs i2m"; fi
# shellcheck disable=SC2046
if $CCX -std=c11 -Wall -Wextra -Werror run/example_api.c $(pkg-config --cflags i2m) -L"$PFX/lib" -Wl,-Bstatic -li2m -Wl,-Bdynamic \
  $(pkg-config --static --libs-only-other --libs-only-l i2m | sed 's/-li2m//') -o "$TMP/example_static"; then
  example example_static
else bad "the example does not link libi2m.a with pkg-config --static"; fi

# the man pages: every option of --help is there, and man renders them
for p in i2m i2m-check i2m-info; do
  miss=""
  for o in $("$PFX/bin/$p" --help 2>&1 | grep -o -- '--[a-z][a-z-]*' | sort -u); do
    grep -q -- "$(echo "$o" | sed 's/-/\\\\-/g')" "$PFX/share/man/man1/$p.1" || miss="$miss $o"
  done
  [ -z "$miss" ] && ok "man page $p.1 has every option" || bad "man page $p.1 lacks:$miss"
done
if command -v man >/dev/null 2>&1; then
  man -l "$PFX/share/man/man1/i2m.1" 2>/dev/null | grep -q "sliver-angle" && ok "man -l renders i2m.1" || bad "man -l i2m.1"
fi

# the Python module against the command line
if "$PY" -c "import numpy, meshio" 2>/dev/null; then
  if PYTHONPATH="$PFX/share/i2m/python" "$PY" - "$BIN/i2m" "$TMP" <<'PYEOF'
import subprocess, sys, numpy as np, meshio, i2m
exe, tmp = sys.argv[1], sys.argv[2]
# two labels in a box, anisotropic voxels, a shifted origin
z, y, x = np.mgrid[:20, :36, :30]
a = np.zeros((20, 36, 30), dtype=np.int16)
a[(x - 14) ** 2 + (y - 17) ** 2 / 1.5 + 4 * (z - 9) ** 2 < 120] = 7
a[(x - 12) ** 2 + (y - 15) ** 2 + 4 * (z - 10) ** 2 < 25] = 300
spacing, origin = (0.8, 0.8, 1.6), (-10.0, 5.0, 20.0)
m = i2m.mesh(a, spacing=spacing, origin=origin, deterministic=1, threads=1,
             size_labels={300: 1.0}, regions=[(-5, 10, 25, 5, 20, 35, 1.5)])
# the same image as a NRRD file for bin/i2m
with open(tmp + "/py.nrrd", "wb") as f:
    f.write(("NRRD0004\ntype: int16\ndimension: 3\nsizes: 30 36 20\nspace: left-posterior-superior\n"
             "space directions: (0.8,0,0) (0,0.8,0) (0,0,1.6)\nspace origin: (-10,5,20)\nendian: little\n"
             "encoding: raw\n\n").encode())
    f.write(a.astype("<i2").tobytes())
subprocess.run([exe, tmp + "/py.nrrd", "-o", tmp + "/py.vtu", "--deterministic", "--threads", "1", "--quiet",
                "--size-label", "300=1", "--region", "-5,10,25,5,20,35:1.5"], check=True)
c = meshio.read(tmp + "/py.vtu")
def volumes(points, tets, mat):
    p = points[tets]
    v = np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0])) / 6
    return {int(l): v[mat == l].sum() for l in np.unique(mat)}
mine = volumes(m.points, m.cells_dict["tetra"], m.cell_data["material"][0])
cli = volumes(c.points, c.cells_dict["tetra"], c.cell_data["material"][0])
nt, ct = len(m.cells_dict["tetra"]), len(c.cells_dict["tetra"])
print("   python: %d tets, volumes %s; bin/i2m: %d tets, volumes %s" % (nt, mine, ct, cli))
assert nt == ct and set(mine) == set(cli) == {7, 300}, "counts or labels differ"
for l in mine:
    assert abs(mine[l] - cli[l]) <= 1e-9 * abs(cli[l]), "label %d: %r vs %r" % (l, mine[l], cli[l])
try:
    i2m.mesh(a, spacing=(0.8, -1, 1))
    raise SystemExit("a negative spacing was accepted")
except i2m.I2MError as e:
    print("   bad spacing: %s" % e)
PYEOF
  then ok "python: i2m.mesh gives the same tets and per-label volumes as bin/i2m"
  else bad "python: i2m.mesh differs from bin/i2m (or failed)"; fi
else
  echo "SKIP python module: numpy or meshio missing"
fi

# DESTDIR staging, then uninstall leaves nothing behind
make --no-print-directory -s install PREFIX=/opt/i2m DESTDIR="$TMP/stage" >/dev/null 2>&1 || bad "make install DESTDIR"
[ -x "$TMP/stage/opt/i2m/bin/i2m" ] && grep -q "^prefix=/opt/i2m" "$TMP/stage/opt/i2m/lib/pkgconfig/i2m.pc" &&
  ok "DESTDIR stages under $TMP/stage/opt/i2m, i2m.pc says /opt/i2m" || bad "DESTDIR staging"
make --no-print-directory -s uninstall PREFIX=/opt/i2m DESTDIR="$TMP/stage" >/dev/null 2>&1 || bad "make uninstall"
left=$(find "$TMP/stage" -type f -o -type l)
[ -z "$left" ] && ok "make uninstall removes every file" || bad "make uninstall left: $left"
exit $fail
