#!/bin/bash
# The sand scene's slip-controlled points (issue 22's cross-check of the
# drawbar-pull curve): configs/tire_soil_sand.json in its load rig at the
# given slips, `cosim sweep --repeat N` (beds of seeds 1..N, each settled once
# into OUT/beds/, then one run per slip and bed, 1.35 s each), timed under the
# shared benchmark lock; then, when CURVE is given (a dbp_curve.csv: e.g.
# run_sand_dbp.sh's OUT/dbp/dbp_curve.csv), the cross-check against it.
#   bash bench/tire_soil/run_sand_slip.sh BUILD_DIR OUT_DIR [SLIPS [N [CURVE]]]
# SLIPS: comma-separated (default 0.05,0.2,0.3); N default 1. Writes OUT_DIR/
# (summary.csv: per slip T_H, T_R, T_P with 95 % intervals), OUT_DIR.time, and
# with CURVE OUT_DIR/cross/ (cross.png, cross_check.csv: the points against
# the curve at their slips, cosim.traction.dbp_cross_check).
set -euo pipefail
USAGE="usage: run_sand_slip.sh BUILD_DIR OUT_DIR [SLIPS [N [CURVE]]]"
BUILD=${1:?$USAGE}
OUT=${2:?$USAGE}
SLIPS=${3:-0.05,0.2,0.3}
N=${4:-1}
CURVE=${5:-}
SCENE=${SCENE:-configs/tire_soil_sand.json}
REF=bench/results/terra_reference_sand_W1000.csv
HERE=$(cd "$(dirname "$0")" && pwd)
bash "$HERE/timed.sh" "$OUT" "$SCENE" \
  "$BUILD/bin/cosim" sweep "$SCENE" --values "scenario.slip=$SLIPS" \
  --repeat "$N" --jobs 1 --out "$OUT" --reference "$REF"
if [ -n "$CURVE" ]; then
  PYTHONPATH="$HERE/../../python" MPLBACKEND=Agg /usr/bin/python3 -m cosim.fig_dbp \
    --curve "$CURVE" --png "$OUT/cross/cross.png" --slip-points "$OUT/summary.csv" \
    --check "$OUT/cross/cross_check.csv" --reference "$REF"
fi
