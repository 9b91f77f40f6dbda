#!/bin/sh
# i2m-check --plot: pictures that tell labels apart, and progress lines.
# - The liver (labels 84, 85, 127, 255; no colour table) at --delta 4 and the knee atlas (49
#   tissues, knee_atlas.ctbl beside it) at --delta 2: the three default cross-sections
#   (cross_section_x/_y/_z.svg) exist; in every picture no two labels share a colour, each two
#   are at least 12 CIE76 units apart in CIELAB (computed here, not by i2m-check), none is
#   near the white background; the legend lists exactly the labels drawn, in their colours;
#   a label has one colour in all pictures; the knee's table colours are kept exactly where
#   they are distinct (the smaller of two clashing labels keeps its colour), and the legend
#   marks the others with '*'; names come from the table.
# - --slice z=Cmm and --slice x=F cut the requested plane: the SVG names the axis and the
#   coordinate, and draws exactly the tets the plane meets (counted here with numpy from the
#   mesh file); a second slice on one axis is cross_section_x_2.svg.
# - Bad --slice values: exit 2, one line on stderr, nothing on stdout.
# - Progress: with --progress-interval 0 (every update) the phases print "N of TOTAL (P%), rate, about S s
#   left" lines on stderr while --json keeps stdout one JSON object; --quiet prints nothing;
#   the default interval (2 s) prints nothing on a run shorter than that.
set -u
BIN="${I2M_BIN:-bin}"
DATA="${I2M_DATA:-../shared/data}"
PY="${PYTHON:-/usr/bin/python3}"
T="$I2M_TMP/plot"
mkdir -p "$T"
fail=0
ok() { echo "ok   $*"; }
bad() { echo "FAIL $*"; fail=1; }

"$BIN/i2m" "$DATA/liver.inr.gz" --delta 4 -o "$T/liver.vtu" --quiet || { echo "FAIL meshing the liver"; exit 1; }
"$BIN/i2m" "$DATA/knee_atlas.nrrd" --delta 2 -o "$T/knee.vtu" --quiet || { echo "FAIL meshing the knee"; exit 1; }

# pictures.py DIR CTBL|- JSON|-: the colour properties of every cross_section*.svg in DIR
cat >"$T/pictures.py" <<'EOF'
import glob, json, math, sys
import xml.etree.ElementTree as ET
NS = "{http://www.w3.org/2000/svg}"
MIN_DE = 12.0

def lab(hexcol):
    rgb = [int(hexcol[i:i + 2], 16) / 255.0 for i in (1, 3, 5)]
    lin = [c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in rgb]
    M = [(0.4124564, 0.3575761, 0.1804375), (0.2126729, 0.7151522, 0.0721750), (0.0193339, 0.1191920, 0.9503041)]
    X, Y, Z = (sum(m * c for m, c in zip(row, lin)) for row in M)
    f = lambda t: t ** (1 / 3) if t > (6 / 29) ** 3 else t / (3 * (6 / 29) ** 2) + 4 / 29
    fx, fy, fz = f(X / 0.95047), f(Y), f(Z / 1.08883)
    return (116 * fy - 16, 500 * (fx - fy), 200 * (fy - fz))

def de(a, b):
    return math.dist(lab(a), lab(b))

d, ctbl, js = sys.argv[1], sys.argv[2], sys.argv[3]
errors, seen = [], {}
files = sorted(glob.glob(d + "/cross_section*.svg"))
if not files:
    errors.append("no cross_section*.svg")
legend_text = {}
for fn in files:
    root = ET.parse(fn).getroot()
    groups = {}
    for g in root.iter(NS + "g"):
        if g.get("class") == "label":
            lab_ = int(g.get("data-label"))
            if lab_ in groups:
                errors.append("%s: label %d in two groups" % (fn, lab_))
            groups[lab_] = g.get("fill").lower()
            if not list(g.iter(NS + "polygon")):
                errors.append("%s: label %d has no polygon" % (fn, lab_))
    legend = {}
    for g in root.iter(NS + "g"):
        if g.get("class") == "legend-entry":
            rect, text = g.find(NS + "rect"), g.find(NS + "text")
            legend[int(g.get("data-label"))] = rect.get("fill").lower()
            legend_text[int(g.get("data-label"))] = text.text
    if legend != groups:
        errors.append("%s: the legend %s differs from the drawn labels %s" % (fn, legend, groups))
    labels = sorted(groups)
    for i, a in enumerate(labels):
        if de(groups[a], "#ffffff") < MIN_DE:
            errors.append("%s: label %d colour %s is near the white background" % (fn, a, groups[a]))
        for b in labels[i + 1:]:
            if groups[a] == groups[b]:
                errors.append("%s: labels %d and %d share colour %s" % (fn, a, b, groups[a]))
            elif de(groups[a], groups[b]) < MIN_DE:
                errors.append("%s: labels %d %s and %d %s only %.1f apart" % (fn, a, groups[a], b, groups[b],
                                                                              de(groups[a], groups[b])))
        if seen.setdefault(a, groups[a]) != groups[a]:
            errors.append("%s: label %d is %s here, %s elsewhere" % (fn, a, groups[a], seen[a]))
kept_checked = 0
if ctbl != "-":
    table = {}
    for line in open(ctbl):
        p = line.split()
        if line.startswith("#") or len(p) < 5:
            continue
        table[int(p[0])] = (p[1], "#%02x%02x%02x" % (int(p[2]), int(p[3]), int(p[4])))
    mesh_labels = sorted(l["label"] for l in json.load(open(js))["fidelity"]["labels"] if l["in_mesh"])
    kept = []  # the rule: by increasing label, a table colour is kept when it is far from white and the kept ones
    for v in mesh_labels:
        if v in table and de(table[v][1], "#ffffff") >= MIN_DE and all(de(table[v][1], table[k][1]) >= MIN_DE for k in kept):
            kept.append(v)
    for v, col in seen.items():
        text = legend_text[v]
        if v in table and table[v][0] not in text:
            errors.append("label %d: the legend '%s' lacks the table's name %s" % (v, text, table[v][0]))
        if v in kept:
            kept_checked += 1
            if col != table[v][1] or text.endswith("*"):
                errors.append("label %d: table colour %s is distinct, yet drawn %s (legend '%s')" % (v, table[v][1], col, text))
        elif v in table and not text.endswith("*"):
            errors.append("label %d: table colour %s replaced by %s without a '*'" % (v, table[v][1], col))
    if kept_checked < 5:
        errors.append("only %d labels with a kept table colour drawn" % kept_checked)
for e in errors[:20]:
    print(e)
print("%d pictures, %d labels, %d table colours kept" % (len(files), len(seen), kept_checked))
sys.exit(1 if errors else 0)
EOF

# ---- default pictures (the knee's run also shows progress lines: checked below) ----
for case in liver knee; do
  if [ $case = liver ]; then img="$DATA/liver.inr.gz"; ctbl=-; else img="$DATA/knee_atlas.nrrd"; ctbl="$DATA/knee_atlas.ctbl"; fi
  rm -rf "$T/$case"
  if ! "$BIN/i2m-check" "$T/$case.vtu" --image "$img" --no-distances --json --plot "$T/$case" --progress-interval 0 \
       >"$T/$case.json" 2>"$T/$case.err"; then
    bad "$case: i2m-check failed: $(cat "$T/$case.err")"
    continue
  fi
  for s in dihedral_histogram.svg cross_section_x.svg cross_section_y.svg cross_section_z.svg; do
    grep -q '</svg>' "$T/$case/$s" 2>/dev/null || bad "$case: $s missing or incomplete"
  done
  [ -e "$T/$case/cross_section.svg" ] && bad "$case: the old cross_section.svg is still written"
  if out=$("$PY" "$T/pictures.py" "$T/$case" "$ctbl" "$T/$case.json"); then ok "$case: $(echo "$out" | tail -n 1)"
  else bad "$case: $out"; fi
done
# the liver's labels 127 and 255 (one colour before) are both drawn, in different colours
grep -l 'data-label="127"' "$T"/liver/cross_section_*.svg | xargs grep -l 'data-label="255"' >/dev/null ||
  bad "liver: no picture shows both 127 and 255"
grep -q 'x (mm, world)' "$T/knee/cross_section_z.svg" && grep -q 'id="scalebar"' "$T/knee/cross_section_z.svg" ||
  bad "knee: no axis in mm or no scale bar"

# ---- chosen slices: the SVG's plane is the one asked for, and it cuts the tets it should ----
# cut.py SVG MESH COORD|-: the SVG's axis and coordinate, its polygons vs the tets the plane meets
cat >"$T/cut.py" <<'EOF'
import sys
import numpy as np, meshio
import xml.etree.ElementTree as ET
svg, mesh, want = sys.argv[1], sys.argv[2], sys.argv[3]
root = ET.parse(svg).getroot()
axis, c = root.get("data-axis"), float(root.get("data-coordinate-mm"))  # (the exact double: %.17g)
m = meshio.read(mesh)
pts = m.points
if want.startswith("frac"):  # fraction of the mesh's box (no --image)
    f = float(want[4:])
    a = "xyz".index(axis)
    want = pts[:, a].min() + f * (pts[:, a].max() - pts[:, a].min())
else:
    want = float(want)
tets = np.concatenate([b.data for b in m.cells if b.type == "tetra"])
z = pts[tets][:, :, "xyz".index(axis)]
expect = int(((z >= c).any(axis=1) & (z < c).any(axis=1)).sum())
drawn = sum(1 for _ in root.iter("{http://www.w3.org/2000/svg}polygon"))
title = "".join(root.find("{http://www.w3.org/2000/svg}text").itertext())
ok = abs(c - want) <= 1e-3 * max(1.0, abs(want)) and drawn == expect and drawn > 0 and ("%s = %.3f mm" % (axis, c)) in title
print("%s = %g mm (wanted %g): %d polygons, %d tets met by the plane; title '%s'" % (axis, c, want, drawn, expect, title))
sys.exit(0 if ok else 1)
EOF
rm -rf "$T/sl"
if "$BIN/i2m-check" "$T/knee.vtu" --image "$DATA/knee_atlas.nrrd" --no-distances --plot "$T/sl" --slice z=12.5mm \
     --slice y=-20mm --quiet --progress-interval 0.05 >/dev/null 2>"$T/sl.err"; then
  [ -s "$T/sl.err" ] && bad "--quiet still prints: $(head -c 200 "$T/sl.err")"
  for s in z:12.5 y:-20; do
    if out=$("$PY" "$T/cut.py" "$T/sl/cross_section_${s%%:*}.svg" "$T/knee.vtu" "${s#*:}"); then ok "knee --slice: $out"
    else bad "knee --slice: $out"; fi
  done
  [ -e "$T/sl/cross_section_x.svg" ] && bad "--slice: an unasked x picture was written"
else
  bad "knee --slice failed: $(cat "$T/sl.err")"
fi
rm -rf "$T/sf"
if "$BIN/i2m-check" "$T/liver.vtu" --plot "$T/sf" --slice x=0.25 --slice x=0.75 >/dev/null 2>"$T/sf.err"; then
  for s in x:frac0.25 x_2:frac0.75; do
    if out=$("$PY" "$T/cut.py" "$T/sf/cross_section_${s%%:*}.svg" "$T/liver.vtu" "${s#*:}"); then ok "liver --slice (fraction of the mesh's box): $out"
    else bad "liver --slice: $out"; fi
  done
else
  bad "liver --slice fractions failed: $(cat "$T/sf.err")"
fi

# ---- bad --slice values: exit 2, one line ----
for v in w=0.5 z=1.5 z=-0.1 z= z=abc z=40cm z=1e999mm x0.5 z=5000mm; do
  "$BIN/i2m-check" "$T/liver.vtu" --image "$DATA/liver.inr.gz" --no-distances --plot "$T/bad" --slice "$v" \
    >"$T/bad.out" 2>"$T/bad.err"
  code=$?
  if [ $code = 2 ] && [ "$(wc -l <"$T/bad.err")" = 1 ] && [ ! -s "$T/bad.out" ] && grep -q "^i2m-check: .*$v" "$T/bad.err"; then :
  else bad "--slice $v: exit $code, stderr '$(cat "$T/bad.err")'"; fi
done
"$BIN/i2m-check" "$T/liver.vtu" --slice z=0.5 >/dev/null 2>"$T/bad.err"
[ $? = 2 ] && [ "$(wc -l <"$T/bad.err")" = 1 ] || bad "--slice without --plot: not one line and exit 2"
ok "bad --slice values: exit 2, one line each"

# ---- progress lines (of the knee's first run, --json --progress-interval 0: every update) ----
"$PY" -c 'import json,sys; json.load(open(sys.argv[1]))' "$T/knee.json" || bad "progress run: stdout is not one JSON object"
if grep -Eq '^quality, dihedral angles and radius-edge ratios: [0-9]+ of [0-9]+ tets \([0-9]+%\), [0-9.e+]+ tets/s, [0-9.]+ s, about [0-9]+ s left$' "$T/knee.err" &&
   grep -Eq '^fidelity, label volumes and components \(3 passes\) done: [0-9]+ tets, ' "$T/knee.err"; then
  ok "progress: $(wc -l <"$T/knee.err") lines at --progress-interval 0, e.g. '$(grep -m1 ' of ' "$T/knee.err")'"
else
  bad "progress: no progress lines: $(head -c 400 "$T/knee.err")"
fi
"$BIN/i2m-check" "$T/liver.vtu" --no-distances >/dev/null 2>"$T/d.err"
[ -s "$T/d.err" ] && bad "a short run prints progress at the default 2 s interval: $(head -c 200 "$T/d.err")"

[ $fail = 0 ] && echo "check plot: all passed"
exit $fail
