# Sourced by the script tests that mesh real images (not a test itself).
# check_guarantees MESH IMAGE REPORT [i2m-check options]: the independent checker on MESH with
# every guarantee of the refinement issue as a threshold, delta and the ratio bound taken from
# the run's JSON REPORT: a valid mesh; radius-edge <= the bound for every tet; interface
# planar angles >= 30 deg (at most 0.1% exceptions); every mesh interface point within delta
# of the image's interfaces; the two-sided 99th percentile <= delta/2; every label of >= 100
# voxels present; per-label volume within 5% for labels of >= 10000 voxels.  Options after
# REPORT go to i2m-check as further thresholds, e.g. --min-dihedral DEG and --max-dihedral DEG
# (every tet's smallest and largest dihedral angle).  The status is the checker's (0: every
# guarantee met).
BIN=${I2M_BIN:-bin}
DATA=${I2M_DATA:-../shared/data}
TMP=${I2M_TMP:-$(mktemp -d)}
PY=${PYTHON:-/usr/bin/python3}

report_param() { # REPORT KEY: a value of the report's "parameters"
  "$PY" -c "import json,sys; print(json.load(open(sys.argv[1]))['parameters'][sys.argv[2]])" "$1" "$2"
}

check_guarantees() {
  _mesh=$1; _image=$2; _rep=$3; shift 3
  _delta=$(report_param "$_rep" delta)
  _ratio=$(report_param "$_rep" ratio)
  _half=$("$PY" -c "import sys; print(float(sys.argv[1]) / 2)" "$_delta")
  "$BIN/i2m-check" "$_mesh" --image "$_image" --max-ratio "$_ratio" --min-facet-angle 30 \
    --facet-angle-exceptions 0.001 --max-mesh-to-image "$_delta" --max-p99 "$_half" \
    --max-volume-error 5 --require-labels 100 "$@"
}
