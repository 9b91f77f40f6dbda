#!/bin/sh
# run/mpirun.sh: runs bin/i2m under MPI on this machine with sensible defaults, and echoes
# the command it runs.
#
#   run/mpirun.sh [-n RANKS] [-t THREADS] [-d] IMAGE OUT [i2m options]
#
#   -n RANKS    MPI processes (default: one per NUMA domain when there are several, else 2)
#   -t THREADS  worker threads per process, set as OMP_NUM_THREADS (default: cores / ranks, >= 1)
#   -d          only print the command
#
# Environment: MPIRUN (the launcher, default mpirun; e.g. MPIRUN=mpirun.mpich), I2M (the
# binary; default bin/i2m, or build/release-mpich/bin/i2m under MPICH's launcher when built
# with make MPI=mpich).  The launcher's flavour comes from `$MPIRUN --version`:
#   Open MPI: --bind-to none (i2m binds each rank's threads to cores of its own with hwloc,
#             rank r of a node from core r x THREADS on), -x OMP_NUM_THREADS,
#             --allow-run-as-root when run as root, --oversubscribe when RANKS > cores,
#             and OMPI_MCA_mpi_yield_when_idle=1 when RANKS x THREADS > cores;
#   MPICH (Hydra) and Intel MPI: -bind-to none (Hydra passes the environment on);
#   any other: -n RANKS only.
# OUT ending in .pvtu: every rank writes its piece OUT_<rank>.vtu (no gather); .vtu, .mesh or
# .msh: one file stitched on rank 0.
set -eu
root=$(cd "$(dirname "$0")/.." && pwd)
usage() {
  sed -n '5,9p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
}

# ---- this machine: cores and NUMA domains (hwloc-calc, else lscpu, else getconf) ----------
count_cores() {
  n=$(hwloc-calc --number-of core machine:0 2>/dev/null || true)
  [ -n "$n" ] || n=$(lscpu -p=CORE,SOCKET 2>/dev/null | grep -v '^#' | sort -u | wc -l | tr -d ' ')
  [ -n "$n" ] && [ "$n" -gt 0 ] 2>/dev/null || n=$(getconf _NPROCESSORS_ONLN 2>/dev/null || echo 1)
  echo "$n"
}
count_numa() {
  n=$(hwloc-calc --number-of numanode machine:0 2>/dev/null || true)
  [ -n "$n" ] || n=$(LC_ALL=C lscpu 2>/dev/null | sed -n 's/^NUMA node(s): *//p')
  [ -n "$n" ] && [ "$n" -gt 0 ] 2>/dev/null || n=1
  echo "$n"
}

ranks=""
threads=""
dry=0
while getopts n:t:dh opt; do
  case $opt in
    n) ranks=$OPTARG ;;
    t) threads=$OPTARG ;;
    d) dry=1 ;;
    *) usage ;;
  esac
done
shift $((OPTIND - 1))
[ $# -ge 2 ] || usage
image=$1
out=$2
shift 2
for v in ${ranks:+"$ranks"} ${threads:+"$threads"}; do
  case $v in '' | *[!0-9]* | 0) echo "run/mpirun.sh: -n and -t take a positive integer (got '$v')" >&2; exit 2 ;; esac
done

cores=$(count_cores)
numa=$(count_numa)
if [ -z "$ranks" ]; then
  if [ "$numa" -gt 1 ]; then ranks=$numa; else ranks=2; fi
fi
if [ -z "$threads" ]; then
  threads=$((cores / ranks))
  [ "$threads" -ge 1 ] || threads=1
fi

# ---- the launcher and its flavour -------------------------------------------------------
MPIRUN=${MPIRUN:-mpirun}
command -v "$MPIRUN" >/dev/null 2>&1 || { echo "run/mpirun.sh: no MPI launcher '$MPIRUN' (set MPIRUN=)" >&2; exit 2; }
version=$("$MPIRUN" --version 2>&1 || true)
case $version in
  *"Open MPI"* | *OpenRTE*) flavour=openmpi ;;
  *HYDRA* | *MPICH* | *"Intel(R) MPI"*) flavour=mpich ;;
  *) flavour=other ;;
esac

if [ -z "${I2M:-}" ]; then
  I2M=$root/bin/i2m
  [ "$flavour" = mpich ] && [ -x "$root/build/release-mpich/bin/i2m" ] && I2M=$root/build/release-mpich/bin/i2m
fi
[ -x "$I2M" ] || { echo "run/mpirun.sh: no executable $I2M (run make, or set I2M=)" >&2; exit 2; }
# an i2m linked with another MPI than the launcher's would run as RANKS separate processes
if command -v ldd >/dev/null 2>&1; then
  lib=$(ldd "$I2M" 2>/dev/null | sed -n 's/^[[:space:]]*\(libmpi[a-z_]*\)\.so.*/\1/p' | head -n 1)
  case "$flavour:$lib" in
    openmpi:libmpich | mpich:libmpi) echo "run/mpirun.sh: warning: $I2M uses $lib, the launcher $MPIRUN is $flavour" >&2 ;;
  esac
fi

export OMP_NUM_THREADS="$threads"
envs="OMP_NUM_THREADS=$threads"
set -- "$image" -o "$out" "$@"
case $flavour in
  openmpi)
    flags="-np $ranks --bind-to none -x OMP_NUM_THREADS"
    [ "$(id -u)" = 0 ] && flags="$flags --allow-run-as-root"
    [ "$ranks" -gt "$cores" ] && flags="$flags --oversubscribe"
    if [ "$((ranks * threads))" -gt "$cores" ] && [ -z "${OMPI_MCA_mpi_yield_when_idle:-}" ]; then
      export OMPI_MCA_mpi_yield_when_idle=1
      envs="$envs OMPI_MCA_mpi_yield_when_idle=1"
    fi ;;
  mpich) flags="-n $ranks -bind-to none" ;;
  *) flags="-n $ranks" ;;
esac
echo "run/mpirun.sh: $ranks rank(s) x $threads thread(s) on $cores core(s), $numa NUMA domain(s); $flavour launcher" >&2
# the command, each argument quoted when it needs to be
quoted=""
for a in "$MPIRUN" $flags "$I2M" "$@"; do
  case $a in
    *[!A-Za-z0-9_./:=,+-]* | '') a="'$(printf '%s' "$a" | sed "s/'/'\\\\''/g")'" ;;
  esac
  quoted="$quoted $a"
done
echo "$envs$quoted"
[ "$dry" = 1 ] && exit 0
# shellcheck disable=SC2086
exec "$MPIRUN" $flags "$I2M" "$@"
