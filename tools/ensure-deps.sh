#!/bin/sh
# Checks what i2m needs.
#   sh tools/ensure-deps.sh build   what building needs (a C compiler with OpenMP, zlib, hwloc;
#                                   MPI is used when present): never installs anything, prints
#                                   one line naming the missing Debian packages
#   sh tools/ensure-deps.sh [all]   what building and testing need (also Open MPI, MPICH, CUnit,
#                                   Python's numpy, meshio, Gmsh and VTK modules, pkg-config):
#                                   as root on Debian/Ubuntu it installs what is missing with
#                                   apt-get; otherwise it prints one line naming the packages
set -u
MODE=${1:-all}
PKGS=""
need() { PKGS="$PKGS $1"; }
CC_CMD=${CC_FOR_DEPS:-cc}
have_header() { printf '#include <%s>\n' "$1" | "$CC_CMD" -E -x c - >/dev/null 2>&1; }
have_openmp() {
  d=$(mktemp -d) || return 1
  printf '#include <omp.h>\nint main(void) { return omp_get_max_threads() < 1; }\n' >"$d/o.c"
  "$CC_CMD" -fopenmp "$d/o.c" -o "$d/o" >/dev/null 2>&1
  s=$?
  rm -rf "$d"
  return $s
}

command -v "$CC_CMD" >/dev/null 2>&1 || { need gcc; CC_CMD=gcc; }
command -v make >/dev/null 2>&1 || need make
have_header zlib.h || need zlib1g-dev
have_header hwloc.h || need libhwloc-dev
if [ "$MODE" = build ]; then
  command -v "$CC_CMD" >/dev/null 2>&1 && ! have_openmp && need "libgomp1 (or your compiler's OpenMP runtime)"
  [ -z "$PKGS" ] && exit 0
  echo "i2m: missing build dependencies; install them with: sudo apt-get install$PKGS" >&2
  exit 1
fi
command -v mpicc >/dev/null 2>&1 || need "libopenmpi-dev"
command -v mpirun >/dev/null 2>&1 || need "openmpi-bin"
# MPICH beside it, for make check-builds (Open MPI stays the default mpicc: higher priority)
command -v mpicc.mpich >/dev/null 2>&1 && command -v mpirun.mpich >/dev/null 2>&1 || need "mpich libmpich-dev"
command -v pgrep >/dev/null 2>&1 || need procps # (tests/scripts/test_mpi_errors.sh finds the ranks to kill)
command -v pkg-config >/dev/null 2>&1 || need pkg-config # (the install test builds the example with it)
have_header CUnit/CUnit.h || need libcunit1-dev
py_has() { [ -x /usr/bin/python3 ] && /usr/bin/python3 -c "import $1" >/dev/null 2>&1; }
py_has "meshio, numpy" || need "python3-meshio python3-numpy"
py_has gmsh || need python3-gmsh
py_has vtk || need python3-vtk9

[ -z "$PKGS" ] && exit 0
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  echo "i2m: installing missing Debian packages:$PKGS" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq >/dev/null 2>&1 || true
  # shellcheck disable=SC2086
  if apt-get install -y -qq --no-install-recommends $PKGS >/dev/null 2>&1; then exit 0; fi
  echo "i2m: apt-get install failed for:$PKGS" >&2
  exit 1
fi
echo "i2m: missing build/test dependencies; install them with: sudo apt-get install$PKGS" >&2
exit 1
