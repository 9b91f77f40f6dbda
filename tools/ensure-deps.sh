#!/bin/sh
# Checks that what i2m builds and tests with is installed.  As root on Debian/Ubuntu it
# installs what is missing with apt-get; otherwise it prints one line naming the packages.
set -u
PKGS=""
need() { PKGS="$PKGS $1"; }
have_header() { printf '#include <%s>\n' "$1" | cc -E -x c - >/dev/null 2>&1; }

command -v cc >/dev/null 2>&1 || need gcc
command -v make >/dev/null 2>&1 || need make
command -v mpicc >/dev/null 2>&1 || need "libopenmpi-dev"
command -v mpirun >/dev/null 2>&1 || need "openmpi-bin"
command -v pgrep >/dev/null 2>&1 || need procps # (tests/scripts/test_mpi_errors.sh finds the ranks to kill)
have_header zlib.h || need zlib1g-dev
have_header hwloc.h || need libhwloc-dev
have_header CUnit/CUnit.h || need libcunit1-dev
[ -x /usr/bin/python3 ] && /usr/bin/python3 -c 'import meshio, numpy' >/dev/null 2>&1 || need "python3-meshio python3-numpy"

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
