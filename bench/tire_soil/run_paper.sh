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
LOCK=${COSIM_BENCH_LOCK:-/tmp/cosim-bench.lock}
flock "$LOCK" bash -c '
  scene=$1 build=$2 out=$3; shift 3
  echo "scene: $scene" > "$out.time"
  echo "args: $*" >> "$out.time"
  echo "load_before: $(cut -d" " -f1-3 /proc/loadavg)" >> "$out.time"
  t0=$(date +%s.%N)
  rc=0
  "$build/bin/cosim" run "$scene" --set output.dir="\"$out\"" --overwrite "$@" > "$out.log" 2>&1 || rc=$?
  t1=$(date +%s.%N)
  echo "wall_s: $(echo "$t1 - $t0" | bc)" >> "$out.time"
  echo "load_after: $(cut -d" " -f1-3 /proc/loadavg)" >> "$out.time"
  echo "rc: $rc" >> "$out.time"
  exit $rc' _ "$SCENE" "$BUILD" "$WORK/$NAME" "$@"
