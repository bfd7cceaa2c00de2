#!/bin/bash
# The sand scene's whole traction-slip curve on N beds (issue 22's headline):
# configs/tire_soil_sand.json in the drawbar-pull rig, `cosim sweep --repeat N`
# (N beds from the generator's seeds 1..N, each settled once into OUT/beds/,
# then one dbp run per bed), timed under the shared benchmark lock.
#   bash bench/tire_soil/run_sand_dbp.sh BUILD_DIR OUT_DIR [N [cosim sweep args...]]
# N defaults to 5, the headline (stop 60: five beds at once on the scene's
# substrate in 59.1 min with the settling, every 95 % half-width from 0 to 40 %
# slip <= 0.039 of the load, the paper scene 222-242 s in that sitting;
# bench/results/sand_calibration.md "The headline on the substrate in the hour";
# stop 54, before the substrate: 55.9 min, <= 0.038).
# writes OUT_DIR/ (the sweep: OUT_DIR/dbp/dbp_curve.csv and dbp.png are the
# curve across the beds with 95 % intervals) and OUT_DIR.time (wall time, load
# before and after, the arguments). The rig (stop 53): the tyre sinks at
# 0.2 m/s to the 1 kN load (reached at t = 0.14 s), the carriage is held back by
# -100 N (a push: the slip starts near zero) for 0.1 s, then the force rises at
# +330 N/s to the scene's end, t = 1.10 s: slip from about -0.05 to 0.40-0.44.
# Until stop 53 the sinkage went at the scene's 0.1 m/s (load at t = 0.28 s),
# the hold was -130 N for 0.15 s and the end 1.35 s: the same ramp rate and end
# force (about 175-185 N), 0.84x the coupled time, and on the same four beds
# the same curve (paired: 24 of 24 T_H/T_R/T_P bins and 8 of 8 sinkage bins
# within their intervals; bench/results/sand_calibration.md "The rig's
# transient cut"). A faster ramp (500 N/s) was not kept: 0.62x, but T_P at
# 0.15-0.20 outside and every bed noisier. The averaging window (stop 54) is
# one lug passage, 2 pi / (32 lugs x 1.8 rad/s) = 0.10908 s: the curve bins
# the rows by their slip averaged over it, each force averaged alike
# (cosim.traction.dbp_curve), so a bin holds whole lug passages (until stop 54:
# 0.1 s, and the rows binned unaveraged).
# The beds run at once (JOBS, default N), each dem on one thread: on 2 vCPUs
# three beds took 61.7 min so, against about 68 for one after the other with
# two threads each (bench/results/sand_calibration.md "The DEM step on three
# beds"); JOBS=1 runs them in turn, dem threads "auto". With more than one job
# the tread runs on one thread too (stop 60: its second thread cost 7 % of a
# sand run's CPU in barrier waits, the whole run's wall time the same alone).
set -euo pipefail
BUILD=${1:?usage: run_sand_dbp.sh BUILD_DIR OUT_DIR [N [cosim sweep args...]]}
OUT=${2:?usage: run_sand_dbp.sh BUILD_DIR OUT_DIR [N [cosim sweep args...]]}
N=${3:-5}
shift $(( $# < 3 ? $# : 3 ))
SCENE=${SCENE:-configs/tire_soil_sand.json}
JOBS=${JOBS:-$N}
THREADS=()
if [ "$JOBS" -gt 1 ]; then THREADS=(--set processes.soil.threads=1 --set processes.tyre.threads=1); fi
bash "$(dirname "$0")/timed.sh" "$OUT" "$SCENE" \
  "$BUILD/bin/cosim" sweep "$SCENE" --values scenario.slip=0.0 \
  --set scenario.rig=dbp --set scenario.sinkage_velocity=0.2 \
  --set scenario.dbp_force_start=-100 --set scenario.dbp_hold=0.1 \
  --set scenario.dbp_force_rate=330 \
  --set scenario.dbp_window=0.10908 --set time.end=1.10 --repeat "$N" --jobs "$JOBS" "${THREADS[@]}" --out "$OUT" \
  --reference bench/results/terra_reference_sand_W1000.csv "$@"
