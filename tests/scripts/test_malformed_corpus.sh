#!/bin/sh
# A generated corpus of malformed images, read by i2m-info (the ASan+UBSan build when it
# exists, else the release one): every file must end in exit 0 (a mutation that left a valid
# image) or exit 1/2 with exactly one line on stderr naming the file, never a signal, a
# sanitizer report or output on stderr beyond that line.  The corpus: the eleven file forms
# i2m reads (NRRD attached raw/gzip and detached, NIfTI .nii/.nii.gz/.hdr+.img, MetaImage
# .mha raw/zlib and .mhd, INR and INR.gz), each cut at several lengths, with bytes flipped in
# its header and its data, and with header fields replaced by absurd values (huge, negative,
# zero, non-numeric sizes and spacings, unknown types): at least 200 files.
set -u
BIN=${I2M_BIN:-bin}
ASAN_BIN=${I2M_ASAN_BIN:-build/asan/bin}
T=${I2M_TMP:-$(mktemp -d)}
PY=${PYTHON:-/usr/bin/python3}
MK="$BIN/i2m-mkimage"
INFO="$ASAN_BIN/i2m-info"
[ -x "$INFO" ] || INFO="$BIN/i2m-info"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:abort_on_error=1"
C="$T/corpus"
mkdir -p "$C/base"

# the valid bases (small: the corpus is about the headers and the streams)
i=0
for f in a.nrrd g.nrrd dn.nhdr a.nii g.nii.gz p.hdr a.mha z.mha dm.mhd a.inr g.inr.gz; do
  extra=""
  case $f in g.nrrd | z.mha) extra="--gzip" ;; esac
  # shellcheck disable=SC2086
  "$MK" --shape two-balls --dims 12,10,8 --type int16 $extra -o "$C/base/$f" >/dev/null || { echo "FAIL mkimage $f"; exit 1; }
  i=$((i + 1))
done

# the mutations, written by Python next to copies of the bases' companions (.raw, .img)
"$PY" - "$C" <<'EOF' || { echo "FAIL generating the corpus"; exit 1; }
import os, re, shutil, sys
C = sys.argv[1]
base = os.path.join(C, "base")
out = os.path.join(C, "bad")
os.makedirs(out, exist_ok=True)
n = 0
def emit(name, data, companions=()):
    global n
    d = os.path.join(out, "%03d" % n)
    os.makedirs(d)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)
    for c in companions:
        shutil.copy(os.path.join(base, c), os.path.join(d, c))
    n += 1
headers = {"dn.nhdr": ["dn.raw"], "p.hdr": ["p.img"], "dm.mhd": ["dm.raw"]}
text_fields = [  # (pattern, replacements) for the text headers
    (rb"sizes: [^\n]*", [b"sizes: 99999999 99999999 99999999", b"sizes: -3 10 8", b"sizes: 0 10 8", b"sizes: x y z", b"sizes: 12 10"]),
    (rb"type: [^\n]*", [b"type: quaternion", b"type: "]),
    (rb"space directions: [^\n]*", [b"space directions: (0,0,0) (0,1,0) (0,0,1)", b"space directions: (nan,0,0) (0,1,0) (0,0,1)", b"space directions: (1,0,0) (1,0,0) (0,0,1)"]),
    (rb"DimSize = [^\n]*", [b"DimSize = 99999999 99999999 99999999", b"DimSize = -12 10 8", b"DimSize = 0 0 0", b"DimSize = 12"]),
    (rb"ElementSpacing = [^\n]*", [b"ElementSpacing = 0 1 1", b"ElementSpacing = -1 1 1", b"ElementSpacing = inf 1 1", b"ElementSpacing = 1e-300 1 1"]),
    (rb"ElementType = [^\n]*", [b"ElementType = MET_OTHER", b"ElementType = "]),
    (rb"HeaderSize = [^\n]*", [b"HeaderSize = 999999999"]),
    (rb"XDIM=\d+", [b"XDIM=99999999", b"XDIM=-4", b"XDIM=0"]),
    (rb"VX=[^\n]*", [b"VX=-1", b"VX=nan", b"VX=0"]),
    (rb"TYPE=[^\n]*", [b"TYPE=complex"]),
]
for name in sorted(os.listdir(base)):
    if name.endswith((".raw", ".img")):
        continue
    data = open(os.path.join(base, name), "rb").read()
    comp = headers.get(name, [])
    stem, ext = name.split(".", 1)
    size = len(data)
    for frac in (0.02, 0.1, 0.3, 0.5, 0.8, 0.97):  # cut short
        emit(name, data[: max(1, int(size * frac))], comp)
    for k in range(8):  # bytes flipped in the first 400 (the header), and in the data
        at = (37 * k + 11) % min(size, 400)
        b = bytearray(data); b[at] ^= 0xFF; emit(name, bytes(b), comp)
    for k in range(3):
        at = size - 1 - 97 * k
        if at > 0:
            b = bytearray(data); b[at] ^= 0x5A; emit(name, bytes(b), comp)
    emit(name, data + b"\x00garbage" * 50, comp)  # trailing junk
    if not name.endswith((".gz",)) and not (name.endswith(".nrrd") and stem == "g") and not (name.endswith(".mha") and stem == "z"):
        for pat, reps in text_fields:
            if re.search(pat, data):
                for r in reps:
                    emit(name, re.sub(pat, r, data, count=1), comp)
    if name == "a.nii":  # binary NIfTI fields: dim, datatype, pixdim, vox_offset
        import struct
        for off, fmt, val in ((40, "<h", 7), (42, "<h", -5), (42, "<h", 32767), (70, "<h", 2048), (70, "<h", 0),
                              (76, "<f", -1.0), (80, "<f", float("nan")), (108, "<f", 1e30), (108, "<f", 12.5),
                              (72, "<h", 3), (252, "<h", 9), (254, "<h", 9)):
            b = bytearray(data); struct.pack_into(fmt, b, off, val); emit(name, bytes(b), comp)
print("corpus: %d malformed files" % n)
EOF

# the fuzzers' finds, kept as regression files (tests/fuzz/regressions/, images by their
# extension; see tests/fuzz/run.sh), join the corpus
REG=tests/fuzz/regressions
if [ -d "$REG" ]; then
  for f in "$REG"/*; do
    case $f in *.md) continue ;; esac
    [ -f "$f" ] || continue
    mkdir -p "$C/bad/reg-$(basename "$f")" && cp "$f" "$C/bad/reg-$(basename "$f")/"
  done
fi

n=0 errors=0 fails=0
for d in "$C"/bad/*; do
  for f in "$d"/*; do
    case $f in *.raw | *.img) continue ;; esac
    n=$((n + 1))
    "$INFO" "$f" >"$T/out" 2>"$T/err"
    rc=$?
    lines=$(wc -l <"$T/err" | tr -d ' ')
    if [ $rc -eq 0 ] && [ "$lines" -eq 0 ]; then
      :
    elif { [ $rc -eq 1 ] || [ $rc -eq 2 ]; } && [ "$lines" -eq 1 ] && grep -qF "$f" "$T/err"; then
      errors=$((errors + 1))
    else
      fails=$((fails + 1))
      echo "FAIL $f: exit $rc, $lines line(s) on stderr:"
      head -n 8 "$T/err"
    fi
  done
done
echo "malformed corpus: $n files read by $INFO: $errors refused with one line, $((n - errors - fails)) still valid, $fails failures"
[ $n -ge 200 ] || { echo "FAIL only $n files in the corpus"; fails=$((fails + 1)); }
[ $errors -ge $((n / 2)) ] || { echo "FAIL fewer than half of the corpus refused: the mutations no longer test the readers"; fails=$((fails + 1)); }
[ $fails -eq 0 ] && echo "test_malformed_corpus: all passed"
[ $fails -eq 0 ]
