#!/bin/sh
# i2m-info --json on each real image gives the voxel count of every label listed in its
# <name>.labels.json (counted by an independent reader), the expected dimensions and format;
# the text output, --help and a bad option behave.  Environment: I2M_BIN, I2M_DATA, I2M_TMP.
set -u
BIN=${I2M_BIN:-bin}
PY=${PYTHON:-/usr/bin/python3}
T=${I2M_TMP:?I2M_TMP must name a scratch directory}
fail=0

# file format dims
IMAGES="knee_atlas.nrrd nrrd 512,512,119
abdominal_atlas.nrrd nrrd 256,256,113
head_colin27.nii.gz nifti 181,217,181
spine_verse009.nii.gz nifti 106,408,48
brain_kmeans_noisy.nii.gz nifti 128,128,62
vertebrae_vbseg.mha metaimage 640,633,299
liver.inr.gz inr 438,353,165"

printf '%s\n' "$IMAGES" | {
  while read -r file format dims; do
    name=${file%%.*}
    if ! "$BIN/i2m-info" --json "$I2M_DATA/$file" >"$T/$name.json" 2>"$T/err"; then
      echo "FAIL $file: $(cat "$T/err")"; fail=1; continue
    fi
    if "$PY" - "$T/$name.json" "$I2M_DATA/$name.labels.json" "$format" "$dims" <<'EOF'
import json, sys
got = json.load(open(sys.argv[1]))
want = json.load(open(sys.argv[2]))["labels_voxel_counts"]
problems = []
if got["labels_voxel_counts"] != want:
    problems.append("label counts differ: %s" % sorted(set(got["labels_voxel_counts"].items()) ^ set(want.items()))[:6])
if got["format"] != sys.argv[3]:
    problems.append("format %s" % got["format"])
if got["dims"] != [int(x) for x in sys.argv[4].split(",")]:
    problems.append("dims %s" % got["dims"])
if sum(got["labels_voxel_counts"].values()) != got["dims"][0] * got["dims"][1] * got["dims"][2]:
    problems.append("counts do not add up to the voxel count")
d = got["direction"]
for c in range(3):
    if abs(sum(d[r][c] ** 2 for r in range(3)) - 1) > 1e-9:
        problems.append("direction column %d is not a unit vector" % c)
if not all(s > 0 for s in got["spacing"]):
    problems.append("spacing %s" % got["spacing"])
if problems:
    print("; ".join(problems))
    sys.exit(1)
print("%d labels, spacing %s, origin %s" % (len(want), got["spacing"], got["origin"]))
EOF
    then echo "ok   $file"; else echo "FAIL $file"; fail=1; fi
  done
  exit $fail
} || fail=1

# i2m-mkimage --from IMAGE --upsample 2 (bench-large's image): dimensions x2, spacing / 2,
# every label's voxel count x8, the image's corner (and so its world box) where it was
"$BIN/i2m-mkimage" --from "$I2M_DATA/spine_verse009.nii.gz" --upsample 2 -o "$T/up.nrrd" >/dev/null &&
  "$BIN/i2m-info" --json "$I2M_DATA/spine_verse009.nii.gz" >"$T/a.json" && "$BIN/i2m-info" --json "$T/up.nrrd" >"$T/b.json" &&
  "$PYTHON" - "$T/a.json" "$T/b.json" <<'EOF' || { echo "FAIL mkimage --upsample"; fail=1; }
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
assert [2 * n for n in a["dims"]] == b["dims"], (a["dims"], b["dims"])
assert all(abs(x / 2 - y) < 1e-6 for x, y in zip(a["spacing"], b["spacing"])), (a["spacing"], b["spacing"])
ca, cb = a["labels_voxel_counts"], b["labels_voxel_counts"]
assert ca.keys() == cb.keys() and all(8 * ca[v] == cb[v] for v in ca), "label counts"
assert all(abs(x - y) < 1e-4 for r, s in zip(a["bounds"], b["bounds"]) for x, y in zip(r, s)), (a["bounds"], b["bounds"])
print("ok   i2m-mkimage --upsample 2: dimensions, spacing, counts x8, world box kept")
EOF

# text output, help, usage errors
"$BIN/i2m-info" "$I2M_DATA/liver.inr.gz" >"$T/liver.txt" 2>&1 && grep -q "438 x 353 x 165" "$T/liver.txt" &&
  grep -q "unsigned\|uint8" "$T/liver.txt" || { echo "FAIL text output"; cat "$T/liver.txt"; fail=1; }
"$BIN/i2m-info" --help | grep -q "usage: i2m-info" || { echo "FAIL --help"; fail=1; }
"$BIN/i2m-info" --bogus >/dev/null 2>&1; [ $? = 2 ] || { echo "FAIL bad option: status not 2"; fail=1; }
"$BIN/i2m-info" >/dev/null 2>&1; [ $? = 2 ] || { echo "FAIL no file: status not 2"; fail=1; }
[ $fail = 0 ] && echo "test_image_info: all passed"
exit $fail
