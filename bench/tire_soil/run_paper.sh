#!/bin/bash
# The paper scene (configs/tire_soil_paper.json, or the deep one with
# SCENE=configs/tire_soil_paper_deep.json): settling, sinkage and 0.5 m of
# travel at 5 % slip, timed under the shared benchmark lock.
#   bash bench/tire_soil/run_paper.sh BUILD_DIR WORK_DIR [NAME [cosim run args...]]
# writes WORK_DIR/NAME/ (the run) and WORK_DIR/NAME.time (wall time, load, the
# arguments); further arguments go to `cosim run` (e.g. --set scenario.rig=load).
set -euo pipefail
BUILD=${1:?usage: run_paper.sh BUILD_DIR WORK_DIR [NAME [cosim run args...]]}
WORK=${2:?usage: run_paper.sh BUILD_DIR WORK_DIR [NAME [cosim run args...]]}
NAME=${3:-paper}
shift $(( $# < 3 ? $# : 3 ))
SCENE=${SCENE:-configs/tire_soil_paper.json}
mkdir -p "$WORK"
bash "$(dirname "$0")/timed.sh" "$WORK/$NAME" "$SCENE" \
  "$BUILD/bin/cosim" run "$SCENE" --set output.dir="\"$WORK/$NAME\"" --overwrite "$@"
