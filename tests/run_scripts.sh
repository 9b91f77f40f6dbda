#!/bin/sh
# Runs every script test tests/scripts/test_*.sh from the project root, a few at a time
# (tests/run_parallel.sh: I2M_TEST_JOBS, default the cores, at most 4); fails if any fails.
# Each script gets I2M_DATA (the real images, read only), a private scratch directory
# (I2M_TMP) and I2M_TEST_TIMEOUT seconds (1200; the longest takes about 6 minutes): a hang
# fails its script at once instead of holding the run until CI's own limit.
set -u
cd "$(dirname "$0")/.."
export I2M_DATA="${I2M_DATA:-$(pwd)/../shared/data}"
export I2M_BIN="${I2M_BIN:-$(pwd)/bin}"
export PYTHON="${PYTHON:-/usr/bin/python3}"
LIMIT=${I2M_TEST_TIMEOUT:-1200}
# test_mpi_mesh.sh runs alone at the end: its ranks and threads already fill the cores (beside
# another test it took 2.4 times as long); the others go the longest first (a free slot takes
# the next one)
SOLO=tests/scripts/test_mpi_mesh.sh
set --
for t in test_mesh_real_images test_whole_components test_threads_real_images test_slivers test_sizing \
  test_mpi_errors test_deterministic test_limits; do
  [ -f "tests/scripts/$t.sh" ] && set -- "$@" "tests/scripts/$t.sh"
done
for t in tests/scripts/test_*.sh; do
  [ -f "$t" ] && [ "$t" != $SOLO ] || continue
  case " $* " in *" $t "*) continue ;; esac
  set -- "$@" "$t"
done
n=$#
fail=0
sh tests/run_parallel.sh "" "$LIMIT" "$@" || fail=1
if [ -f $SOLO ]; then
  n=$((n + 1))
  I2M_TEST_JOBS=1 sh tests/run_parallel.sh "" "$LIMIT" $SOLO || fail=1
fi
echo "script tests: $n scripts, $( [ $fail = 0 ] && echo all passed || echo FAILURES)"
exit $fail
