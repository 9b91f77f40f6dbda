#!/bin/sh
# make fuzz: each libFuzzer harness of DIR (built by the Makefile with clang, ASan and UBSan)
# runs SECONDS, seeded with small images in every format i2m reads and with the meshes its
# writers make (VTU compressed and raw, and VTK's writer's; each seed prefixed by the byte that
# picks its extension, see fuzz_common.h).
# Prints each harness's executions and coverage; crashes go to DIR/crashes/ (turn each into
# a regression file under tests/fuzz/regressions/, which make check reads).
#   sh tests/fuzz/run.sh DIR SECONDS
set -u
DIR=$1
SECS=${2:-60}
BIN=${I2M_BIN:-bin}
W="$DIR/work"
rm -rf "$W"
mkdir -p "$W/seed_image" "$W/seed_mesh" "$W/corpus_image" "$W/corpus_mesh" "$DIR/crashes"

# seed FILE INDEX DEST: the byte INDEX then the file
seed() { { printf "\\$(printf '%03o' "$2")"; cat "$1"; } >"$3/$(basename "$1").seed"; }
k=0
for f in a.nrrd b.nrrd c.nii d.nii.gz e.mha f.mha g.inr h.inr.gz; do
  case $f in b.nrrd | f.mha) z=--gzip ;; *) z= ;; esac
  # shellcheck disable=SC2086
  "$BIN/i2m-mkimage" --shape two-balls --dims 9,8,7 --type int16 $z -o "$W/$f" >/dev/null || exit 1
done
seed "$W/a.nrrd" 0 "$W/seed_image"; seed "$W/b.nrrd" 0 "$W/seed_image"; seed "$W/c.nii" 2 "$W/seed_image"
seed "$W/d.nii.gz" 3 "$W/seed_image"; seed "$W/e.mha" 5 "$W/seed_image"; seed "$W/f.mha" 5 "$W/seed_image"
seed "$W/g.inr" 7 "$W/seed_image"; seed "$W/h.inr.gz" 8 "$W/seed_image"
"$BIN/i2m-mkimage" --shape ball --dims 8,8,8 -o "$W/m.nrrd" >/dev/null || exit 1
k=0
for ext in vtu mesh msh; do
  "$BIN/i2m" "$W/m.nrrd" -o "$W/m.$ext" --quiet --threads 1 || exit 1
  seed "$W/m.$ext" $k "$W/seed_mesh"
  k=$((k + 1))
done
for v in "2.2" "2.2 --ascii" "4.1 --ascii"; do # (the Gmsh reader's other versions and encodings)
  f="$W/m$(echo "$v" | tr -d ' .-').msh"
  # shellcheck disable=SC2086
  "$BIN/i2m" "$W/m.nrrd" -o "$f" --msh-format $v --quiet --threads 1 || exit 1
  seed "$f" 2 "$W/seed_mesh"
done
# VTU: zlib-compressed (the default, above), raw, and the interfaces file
"$BIN/i2m" "$W/m.nrrd" -o "$W/m_raw.vtu" --vtu-raw --quiet --threads 1 || exit 1
seed "$W/m_raw.vtu" 0 "$W/seed_mesh"
seed "$W/m.interfaces.vtu" 0 "$W/seed_mesh"
# and as VTK's own writer writes it by default (appended base64), when python3 has vtk
PY=${PYTHON:-/usr/bin/python3}
if "$PY" -c 'import vtk' 2>/dev/null; then
  "$PY" -c 'import sys, vtk
r = vtk.vtkXMLUnstructuredGridReader(); r.SetFileName(sys.argv[1]); r.Update()
w = vtk.vtkXMLUnstructuredGridWriter(); w.SetInputData(r.GetOutput()); w.SetFileName(sys.argv[2])
sys.exit(w.Write() != 1)' "$W/m.vtu" "$W/m_vtk.vtu" && seed "$W/m_vtk.vtu" 0 "$W/seed_mesh"
fi

status=0
for h in image mesh; do
  b="$DIR/fuzz_$h"
  [ -x "$b" ] || { echo "fuzz: no $b"; exit 1; }
  echo "fuzz_$h: $SECS s"
  TMPDIR="$W" "$b" -max_total_time="$SECS" -max_len=65536 -timeout=20 -rss_limit_mb=4096 -print_final_stats=1 \
    -artifact_prefix="$DIR/crashes/$h-" "$W/corpus_$h" "$W/seed_$h" >"$W/$h.log" 2>&1 || status=1
  grep -E "^#[0-9]+[[:space:]]+DONE|stat::number_of_executed_units|stat::peak_rss_mb|ERROR|SUMMARY" "$W/$h.log" | head -n 8
done
found=$(find "$DIR/crashes" -type f | wc -l)
echo "fuzz: $found crash file(s) in $DIR/crashes"
[ "$found" -eq 0 ] || status=1
exit $status
