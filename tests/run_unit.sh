#!/bin/sh
# Runs every CUnit test program in $1 (built for configuration $2), a few at a time
# (tests/run_parallel.sh: I2M_TEST_JOBS); fails if any fails.
set -u
dir=$1; cfg=$2
here=$(cd "$(dirname "$0")" && pwd)
export I2M_DATA="${I2M_DATA:-$here/../../shared/data}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1}"
# the longest first (a free slot takes the next one), then the others
set --
for t in "$dir"/test_delaunay_kernel "$dir"/test_dist_sched "$dir"/test_geom_predicates "$dir"/test_image_read "$dir"/test_*; do
  [ -x "$t" ] || continue
  case " $* " in *" $t "*) continue ;; esac
  set -- "$@" "$t"
done
fail=0
sh "$here/run_parallel.sh" "[$cfg] " 0 "$@" || fail=1
echo "unit tests [$cfg]: $# programs, $( [ $fail = 0 ] && echo all passed || echo FAILURES)"
exit $fail
