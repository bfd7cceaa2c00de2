#!/bin/bash
# The sand scene's whole traction-slip curve on N beds (issue 22's headline):
# configs/tire_soil_sand.json in the drawbar-pull rig, `cosim sweep --repeat N`
# (N beds from the generator's seeds 1..N, each settled once into OUT/beds/,
# then one dbp run per bed), timed under the shared benchmark lock.
#   bash bench/tire_soil/run_sand_dbp.sh BUILD_DIR OUT_DIR [N [cosim sweep args...]]
# writes OUT_DIR/ (the sweep: OUT_DIR/dbp/dbp_curve.csv and dbp.png are the
# curve across the beds with 95 % intervals) and OUT_DIR.time (wall time, load
# before and after, the arguments). The ramp: the carriage held back by -130 N
# (a push: the curve starts near zero slip) for 0.15 s after the sinkage, then
# +330 N/s to the scene's end, t = 1.35 s: slip from about -0.05 to 0.40-0.45
# at 1 kN. (Stop 50 ran to 1.40 s, as the running slip of one bed had only
# just reached 0.40 at 1.35 s; but the curve is binned by the measured slip of
# each row, and in stop 50's four beds that reached 0.40 at t = 1.27-1.34 s:
# by 1.35 s every bed has filled the 0.35-0.40 bin, the last of the 0-40 %
# the curve is read over.)
# The beds run at once (JOBS, default N), each dem on one thread: on 2 vCPUs
# three beds took 61.7 min so, against about 68 for one after the other with
# two threads each (bench/results/sand_calibration.md "The DEM step on three
# beds"); JOBS=1 runs them in turn, dem threads "auto".
set -euo pipefail
BUILD=${1:?usage: run_sand_dbp.sh BUILD_DIR OUT_DIR [N [cosim sweep args...]]}
OUT=${2:?usage: run_sand_dbp.sh BUILD_DIR OUT_DIR [N [cosim sweep args...]]}
N=${3:-3}
shift $(( $# < 3 ? $# : 3 ))
SCENE=${SCENE:-configs/tire_soil_sand.json}
JOBS=${JOBS:-$N}
THREADS=()
if [ "$JOBS" -gt 1 ]; then THREADS=(--set processes.soil.threads=1); fi
bash "$(dirname "$0")/timed.sh" "$OUT" "$SCENE" \
  "$BUILD/bin/cosim" sweep "$SCENE" --values scenario.slip=0.0 \
  --set scenario.rig=dbp --set scenario.dbp_force_start=-130 \
  --set scenario.dbp_force_rate=330 --set scenario.dbp_hold=0.15 \
  --set scenario.dbp_window=0.1 --set time.end=1.35 --repeat "$N" --jobs "$JOBS" "${THREADS[@]}" --out "$OUT" \
  --reference bench/results/terra_reference_sand_W1000.csv "$@"
