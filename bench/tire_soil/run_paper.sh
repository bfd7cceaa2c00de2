#!/bin/bash
# The paper scene (configs/tire_soil_paper.json, or the deep one with
# SCENE=configs/tire_soil_paper_deep.json): settling, sinkage and 0.5 m of
# travel at 5 % slip, timed under the shared benchmark lock.
#   bash bench/tire_soil/run_paper.sh BUILD_DIR WORK_DIR [NAME]
# writes WORK_DIR/NAME/ (the run) and WORK_DIR/NAME.time (wall time, load).
set -euo pipefail
BUILD=${1:?usage: run_paper.sh BUILD_DIR WORK_DIR [NAME]}
WORK=${2:?usage: run_paper.sh BUILD_DIR WORK_DIR [NAME]}
NAME=${3:-paper}
SCENE=${SCENE:-configs/tire_soil_paper.json}
mkdir -p "$WORK"
LOCK=${COSIM_BENCH_LOCK:-/tmp/cosim-bench.lock}
flock "$LOCK" bash -c '
  echo "scene: $1" > "$3.time"
  echo "load_before: $(cut -d" " -f1-3 /proc/loadavg)" >> "$3.time"
  t0=$(date +%s.%N)
  "$2/bin/cosim" run "$1" --set output.dir="\"$3\"" --overwrite > "$3.log" 2>&1
  rc=$?
  t1=$(date +%s.%N)
  echo "wall_s: $(echo "$t1 - $t0" | bc)" >> "$3.time"
  echo "load_after: $(cut -d" " -f1-3 /proc/loadavg)" >> "$3.time"
  echo "rc: $rc" >> "$3.time"
  exit $rc' _ "$SCENE" "$BUILD" "$WORK/$NAME"
