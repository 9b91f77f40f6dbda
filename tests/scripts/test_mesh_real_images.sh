#!/bin/sh
# Every real image in $I2M_DATA meshes with default options, and the independent checker
# confirms every guarantee on the written file (see guarantees.sh).  Formats are rotated so
# that all three writers are exercised.  On every image, every 6-connected image component of
# at least 10,000 voxels must also come out as one piece (before the repair of fragments the
# liver's label 255 came out as 11 pieces; before the component rule the knee's label 41 as 2-3).
# The liver, the spine and the noisy brain are meshed and checked the same way (and at 1 and 4
# threads) by test_threads_real_images.sh, which make check also runs: here the four others
# (I2M_IMAGES: another list).
set -eu
. "$(dirname "$0")/guarantees.sh"
fail=0
n=0
for img in ${I2M_IMAGES:-knee_atlas.nrrd abdominal_atlas.nrrd head_colin27.nii.gz vertebrae_vbseg.mha}; do
  [ -f "$DATA/$img" ] || { echo "missing $DATA/$img"; fail=1; continue; }
  case $n in 0) ext=vtu;; 1) ext=mesh;; *) ext=msh;; esac
  n=$(( (n + 1) % 3 ))
  out="$TMP/${img%%.*}.$ext"
  rep="$TMP/${img%%.*}.json"
  start=$(date +%s)
  if ! timeout 900 "$BIN/i2m" "$DATA/$img" -o "$out" --report "$rep" --quiet; then
    echo "FAIL $img: i2m failed"; fail=1; continue
  fi
  if check_guarantees "$out" "$DATA/$img" "$rep" --require-whole 10000 >"$TMP/check.txt" 2>&1; then
    echo "ok   $img ($ext, delta $(report_param "$rep" delta) mm, $(( $(date +%s) - start )) s): $(grep -E '^mesh ' "$TMP/check.txt" | cut -d: -f2)"
  else
    echo "FAIL $img:"; grep -E "VIOLATED|INVALID|validity|two-sided|mesh->image" "$TMP/check.txt"; fail=1
  fi
  rm -f "$out"
done
exit $fail
