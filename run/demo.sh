#!/bin/sh
# make demo: meshes the SPL knee atlas shipped in run/data end to end with default options
# and the sliver perturbation (--sliver-angle 5, for finite-element use), checks the mesh
# independently against the image, and draws the pictures.
set -eu
cd "$(dirname "$0")/.."
IMG=run/data/knee_atlas.nrrd
OUT=run/out
mkdir -p "$OUT"
echo "i2m demo: meshing $IMG (SPL/NAC knee atlas, 49 tissues) with default options and --sliver-angle 5"
bin/i2m "$IMG" -o "$OUT/knee.vtu" --sliver-angle 5 --report "$OUT/knee_report.json"
echo
echo "i2m demo: checking the mesh independently against the image"
if bin/i2m-check "$OUT/knee.vtu" --image "$IMG" --plot "$OUT/plots" --max-ratio 2 --min-facet-angle 30 \
     --facet-angle-exceptions 0.001 --require-labels 100 --max-volume-error 5 >"$OUT/knee_check.txt"; then
  verdict="passes"
else
  verdict="FAILS (see the file)"
fi
grep -E "^validity|dihedral angles|mesh->image|two-sided|^result" "$OUT/knee_check.txt" | sed 's/^/  /'
cat <<MSG

  mesh         $OUT/knee.vtu      (open in ParaView; it overlays the image in 3D Slicer)
  report       $OUT/knee_report.json
  check        $OUT/knee_check.txt   ($verdict)
  pictures     $OUT/plots/dihedral_histogram.svg
               $OUT/plots/cross_section_x.svg, _y.svg, _z.svg
MSG
