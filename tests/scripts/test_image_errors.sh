#!/bin/sh
# Error paths of the image readers, seen from i2m-info: for every bad input (truncated and
# corrupt gzip, headers that lie about sizes, unknown types, non-3-D images, empty files, a
# directory, a missing file, garbage, absurd sizes, non-integer voxels, sheared grids) the
# program must exit with a non-zero status that is not a signal, print nothing on stdout and
# exactly one line on stderr naming the file and the problem.  Run with the release binary and,
# when it exists, the ASan+UBSan one (which aborts on any sanitizer report or leak).
# Environment (tests/run_scripts.sh): I2M_BIN, I2M_DATA, I2M_TMP (scratch, removed afterwards).
set -u
BIN=${I2M_BIN:-bin}
ASAN_BIN=${I2M_ASAN_BIN:-build/asan/bin}
T=${I2M_TMP:?I2M_TMP must name a scratch directory}
MK="$BIN/i2m-mkimage"
fail=0
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:abort_on_error=1"

[ -x "$BIN/i2m-info" ] && [ -x "$MK" ] || { echo "missing $BIN/i2m-info or $MK"; exit 1; }

# ---- the bad files, all in $T ----
mk() { "$MK" "$@" >/dev/null || { echo "i2m-mkimage $* failed"; fail=1; }; }
mk --dims 40,40,40 --shape noise --type int16 --gzip -o "$T/trunc.nrrd" --truncate-bytes 3000
mk --dims 40,40,40 --shape noise -o "$T/trunc.nii.gz" --truncate-bytes 4
mk --dims 40,40,40 --shape noise --gzip -o "$T/trunc.mha" --truncate-bytes 100
mk --dims 40,40,40 --shape noise --gzip -o "$T/corrupt.nrrd" --corrupt-at -2000
mk --dims 40,40,40 --shape noise -o "$T/corrupt.inr.gz" --corrupt-at -6
mk --dims 20,20,20 --lie-dims 20,20,40 -o "$T/lie.nrrd"
mk --dims 20,20,20 --lie-dims 20,20,40 --gzip -o "$T/lie.mha"
mk --dims 20,20,20 --lie-dims 20,20,40 -o "$T/lie.nii.gz"
mk --dims 20,20,20 --lie-dims 20,40,20 --type int16 -o "$T/lie.inr"
mk --dims 20,20,20 --ndim 2 -o "$T/flat.nii"
mk --dims 20,20,20 --ndim 2 -o "$T/flat.nrrd"
mk --dims 20,20,20 --ndim 2 -o "$T/flat.mha"
mk --dims 20,20,20 --ndim 5 -o "$T/time.nii.gz"
mk --dims 20,20,20 --lie-dims 32767,32767,32767 -o "$T/absurd.nii.gz"
mk --dims 5,5,5 --shape speck --labels 3 --type int16 --scale 0.5,0.25 -o "$T/scaled.nii"
# a .hdr/.img pair whose .img is cut: the message names the header the user gave, too
mk --dims 6,5,4 -o "$T/pair.hdr"
head -c 60 "$T/pair.img" >"$T/pair.cut" && mv "$T/pair.cut" "$T/pair.img"
# control characters in a bad field (a terminal escape, a ^A) come out as '?'
printf 'NRRD0004\ntype: \033[31mred\001\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n12345678' >"$T/ctrl.nrrd"
printf 'NRRD0004\ntype: quaternion\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n12345678' >"$T/type.nrrd"
printf 'ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_QUATERNION\nElementDataFile = LOCAL\n12345678' >"$T/type.mha"
printf 'NRRD0004\ntype: uchar\ndimension: 3\nsizes: 100000 100000 100000\nencoding: raw\n\n12345678' >"$T/absurd.nrrd"
printf 'NRRD0004\ntype: uchar\ndimension: 3\nsizes: 100000 100000 100000\nencoding: gzip\n\n' >"$T/absurdgz.nrrd"
dd if="$I2M_DATA/liver.inr.gz" bs=100 skip=10 count=3 2>/dev/null >>"$T/absurdgz.nrrd"
printf 'NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 -2 2\nencoding: raw\n\n12345678' >"$T/negative.nrrd"
printf 'NRRD0004\ntype: float\ndimension: 3\nsizes: 2 1 1\nendian: little\nencoding: raw\n\n\000\000\200\077\000\000\300\177' >"$T/nan.nrrd"
printf 'NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\nspace: LPS\nspace directions: (1,0,0) (0.3,1,0) (0,0,1)\nencoding: raw\n\n\001' >"$T/shear.nrrd"
printf 'NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\ndata file: nothere.raw\n' >"$T/nodata.nhdr"
printf 'ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nHeaderSize = 500\nElementDataFile = headersize.raw\n' >"$T/headersize.mhd"
printf '12345678' >"$T/headersize.raw"
: >"$T/empty.nii"
mkdir -p "$T/dir.nrrd"
dd if="$I2M_DATA/liver.inr.gz" of="$T/garbage.nrrd" bs=1000 skip=5 count=4 2>/dev/null
dd if="$I2M_DATA/liver.inr.gz" of="$T/garbage.bin" bs=1000 skip=9 count=4 2>/dev/null
dd if="$I2M_DATA/liver.inr.gz" of="$T/garbage.nii" bs=1000 skip=13 count=4 2>/dev/null
printf 'this is plain text, not an image\n' >"$T/garbage.mha"

# file|word expected in the message
CASES="trunc.nrrd|gzip stream ends after
trunc.nii.gz|truncated gzip
trunc.mha|truncated gzip
corrupt.nrrd|corrupt gzip
corrupt.inr.gz|corrupt gzip
lie.nrrd|header says 20x20x40
lie.mha|header says 20x20x40
lie.nii.gz|header says 20x20x40
lie.inr|holds only
flat.nii|not a 3-D image (dim[0] = 2)
flat.nrrd|not a 3-D image
flat.mha|not a 3-D image
time.nii.gz|not a 3-D image
absurd.nii.gz|cannot hold
absurd.nrrd|holds only
absurdgz.nrrd|cannot hold
negative.nrrd|must be positive
negspacing.mha|a spacing must be a positive number
negspacing.inr|a spacing must be a positive number
negspacings.nrrd|a spacing must be a positive number
negpixdim.nii|a spacing must be a positive number
far16.nrrd|too far for its 1 mm voxels
far20.mha|too far for its 1 mm voxels
tinyspacing.nii|outside what i2m meshes
type.nrrd|unknown type \"quaternion\"
ctrl.nrrd|unknown type \"?[31mred?\"
type.mha|element type
scaled.nii|non-integer
pair.hdr|holds only 60 bytes
headersize.mhd|HeaderSize 500 goes past the end
nan.nrrd|NaN
shear.nrrd|sheared
nodata.nhdr|No such file
h/outside.nhdr|outside the header's directory
h/passwd.nhdr|outside the header's directory
h/link.nhdr|outside the header's directory
h/outside.mhd|outside the header's directory
empty.nii|empty file
dir.nrrd|is a directory
missing.nrrd|No such file or directory
garbage.nrrd|not a NRRD file
garbage.bin|unknown image format
garbage.nii|not a NIfTI-1 file
garbage.mha|not a MetaImage file"

# a negative spacing, in each format that states spacings as such: refused alike (a flipped
# axis belongs in the direction matrix: NRRD space directions, a NIfTI sform)
mk --spacing -1,1,1 -o "$T/negspacing.mha"
mk --spacing 1,-2,1 -o "$T/negspacing.inr"
mk --spacing 1,1,-1 --nrrd-space spacings -o "$T/negspacings.nrrd"
mk --spacing -1,1,1 --nifti-form qform -o "$T/negpixdim.nii"

# geometry that doubles cannot mesh: an origin 1e16 or 1e20 mm away, voxels of 1e-9 mm
mk --origin 1e16,0,0 -o "$T/far16.nrrd"
mk --origin 0,-1e20,0 -o "$T/far20.mha"
mk --spacing 1e-9,1e-9,1e-9 -o "$T/tinyspacing.nii"

# detached headers whose data file lies outside their directory: relative, absolute, through
# a symbolic link (a header must not turn any file on the machine into label values)
mkdir -p "$T/h/d"
mk --dims 6,5,4 -o "$T/h/ok.nhdr"
mv "$T/h/ok.raw" "$T/secret.raw"
sed 's|^data file: .*|data file: ../secret.raw|' "$T/h/ok.nhdr" >"$T/h/outside.nhdr"
sed 's|^data file: .*|data file: /etc/passwd|' "$T/h/ok.nhdr" >"$T/h/passwd.nhdr"
ln -s ../secret.raw "$T/h/link.raw"
sed 's|^data file: .*|data file: link.raw|' "$T/h/ok.nhdr" >"$T/h/link.nhdr"
cp "$T/secret.raw" "$T/h/d/inside.raw"
sed 's|^data file: .*|data file: d/inside.raw|' "$T/h/ok.nhdr" >"$T/h/inside.nhdr"
mk --dims 6,5,4 -o "$T/h/okm.mhd"
sed 's|^ElementDataFile = .*|ElementDataFile = ../secret.raw|' "$T/h/okm.mhd" >"$T/h/outside.mhd"

check() { # check INFO FILE WORD
  info=$1; file=$2; word=$3
  "$info" "$T/$file" >"$T/out" 2>"$T/err"
  status=$?
  lines=$(wc -l <"$T/err" | tr -d ' ')
  msg=$(cat "$T/err")
  if [ "$status" -eq 0 ] || [ "$status" -ge 128 ]; then
    echo "FAIL $info $file: exit status $status"; fail=1
  elif [ "$lines" != 1 ]; then
    echo "FAIL $info $file: $lines lines on stderr:"; head -n 20 "$T/err"; fail=1
  elif LC_ALL=C grep -q '[[:cntrl:]]' "$T/err"; then
    echo "FAIL $info $file: a control character on stderr"; fail=1
  elif [ -s "$T/out" ]; then
    echo "FAIL $info $file: output on stdout"; fail=1
  elif ! printf '%s\n' "$msg" | grep -F "$file" >/dev/null; then
    echo "FAIL $info $file: message does not name the file: $msg"; fail=1
  elif ! printf '%s\n' "$msg" | grep -F -- "$word" >/dev/null; then
    echo "FAIL $info $file: message lacks \"$word\": $msg"; fail=1
  else
    echo "ok   $file: $msg"
  fi
}

for info in "$BIN/i2m-info" "$ASAN_BIN/i2m-info"; do
  [ -x "$info" ] || { echo "(no $info: skipped)"; continue; }
  echo "== $info"
  printf '%s\n' "$CASES" | while IFS='|' read -r file word; do
    word=$(printf '%s' "$word" | sed 's/\\"/"/g')
    check "$info" "$file" "$word"
    [ $fail = 0 ] || exit 1
  done || fail=1
  "$info" "$T/h/inside.nhdr" >/dev/null || { echo "FAIL $info: a data file in a subdirectory of the header's was refused"; fail=1; }
  # a good file still reads (guards against a reader that fails on everything)
  "$MK" --shape two-balls --dims 30,20,10 --gzip -o "$T/good.nrrd" && "$info" "$T/good.nrrd" >/dev/null ||
    { echo "FAIL $info: good.nrrd not read"; fail=1; }
done
# --allow-external-data reads what is refused by default
if [ -x "$BIN/i2m" ]; then
  if "$BIN/i2m" "$T/h/outside.nhdr" -o "$T/ext.vtu" --quiet --allow-external-data; then echo "ok   --allow-external-data reads h/outside.nhdr"
  else echo "FAIL i2m --allow-external-data h/outside.nhdr"; fail=1; fi
fi
[ $fail = 0 ] && echo "test_image_errors: all passed"
exit $fail
