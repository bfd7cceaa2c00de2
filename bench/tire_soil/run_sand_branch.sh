#!/bin/bash
# Issue 22's serial-vs-implicit row, paired by branching (`cosim run --branch`):
# the sand scene in the drawbar-pull rig (the headline's settings, as
# run_sand_dbp.sh) runs serial on saved beds with a checkpoint every 0.05 s;
# from chosen checkpoints the same state continues under the implicit scheme
# for one lug passage (0.10908 s), and compare_branch.py sets each window
# against the serial run's own continuation (the same steps, bit for bit what
# a serial branch gives: tests/reliability/test_branch.py).
#   bash bench/tire_soil/run_sand_branch.sh serial BUILD OUT BED.h5...
#     OUT/runs/seed<i>/ from the i-th bed, to time.end 0.80 s (END=...)
#   bash bench/tire_soil/run_sand_branch.sh branch BUILD OUT SCHEME SEED:STEP...
#     OUT/<scheme>/seed<SEED>_k<STEP>/ from OUT/runs/seed<SEED>/checkpoint_<STEP>.h5
# Each stage runs its runs at once (JOBS at a time, default all), dem on one
# thread, under the shared benchmark lock (timed.sh: OUT/<stage>[_<scheme>].time);
# DRY=1 only writes and prints OUT/<stage>[_<scheme>].cmds. SETS adds --set
# arguments to each branch (as shell words), TAG a suffix to <scheme> in its
# directory: SETS="--set coupling.implicit.tolerance=1e-3" TAG=_tol1e-3.
# Stop 56 (bench/results/sand_calibration.md "Convergence: serial vs implicit"):
# the serial stage on the headline's beds 1-3 (OUT/beds of run_sand_dbp.sh; bit
# for bit the headline's runs), then
#   SETS="--set coupling.implicit.tolerance=1e-3" TAG=_tol1e-3 JOBS=3 \
#     bash bench/tire_soil/run_sand_branch.sh branch BUILD OUT implicit \
#     1:24000 2:28000 3:32000 1:56000 2:60000 3:52000
#   JOBS=3 bash bench/tire_soil/run_sand_branch.sh branch BUILD OUT serial (the same)
#   PYTHONPATH=python /usr/bin/python3 bench/tire_soil/compare_branch.py OUT \
#     --b implicit_tol1e-3 --group "5%:1:24000,2:28000,3:32000;20%:1:56000,2:60000,3:52000"
# (the implicit stage 2 087 s, the serial 259 s; the stop's serial stage ran
# from an equivalent command with checkpoint keep 20).
set -euo pipefail
STAGE=${1:?usage: run_sand_branch.sh serial|branch BUILD OUT ...}
BUILD=${2:?BUILD}
OUT=${3:?OUT}
shift 3
SCENE=${SCENE:-configs/tire_soil_sand.json}
END=${END:-0.80}
WINDOW=0.10908
DT=1.25e-5
RIG=(--set scenario.slip=0.0 --set scenario.rig=dbp --set scenario.sinkage_velocity=0.2
     --set scenario.dbp_force_start=-100 --set scenario.dbp_hold=0.1
     --set scenario.dbp_force_rate=330 --set scenario.dbp_window=$WINDOW
     --set processes.soil.threads=1 --set 'coupling.affinity="none"')
mkdir -p "$OUT"
cmds=()
SCHEME= TAG=${TAG:-}
case "$STAGE" in
serial)
  i=0
  for bed in "$@"; do
    i=$((i + 1))
    cmds+=("$BUILD/bin/cosim run $SCENE --overwrite --quiet ${RIG[*]@Q} --set time.end=$END \
--set 'processes.soil.particles={\"file\": \"$(realpath "$bed")\"}' \
--set 'checkpoint={\"every\": 4000, \"keep\": 40}' --set 'output.dir=\"$OUT/runs/seed$i\"'")
  done ;;
branch)
  SCHEME=${1:?SCHEME}
  shift
  for sk in "$@"; do
    seed=${sk%%:*} step=${sk##*:}
    ref="$OUT/runs/seed$seed"
    bed=$(/usr/bin/python3 -c "import h5py,json,sys; c=json.loads(h5py.File(sys.argv[1],'r').attrs['config']); print(c['processes']['soil']['particles']['file'])" "$ref/checkpoint_$step.h5")
    end=$(/usr/bin/python3 -c "print(repr(round(($step * $DT + $WINDOW) / $DT) * $DT))")
    cmds+=("$BUILD/bin/cosim run $SCENE --overwrite --quiet ${RIG[*]@Q} --set time.end=$end \
--set 'processes.soil.particles={\"file\": \"$bed\"}' --set 'coupling.scheme=\"$SCHEME\"' \
--set 'output.dir=\"$OUT/$SCHEME$TAG/seed${seed}_k$step\"' ${SETS:-} --branch $ref/checkpoint_$step.h5")
  done ;;
*) echo "run_sand_branch.sh: stage '$STAGE' is neither serial nor branch" >&2; exit 1 ;;
esac
JOBS=${JOBS:-${#cmds[@]}}
NAME=$STAGE${SCHEME:+_$SCHEME}${TAG:-}
printf '%s\n' "${cmds[@]}" > "$OUT/$NAME.cmds"
if [ -n "${DRY:-}" ]; then cat "$OUT/$NAME.cmds"; exit 0; fi
bash "$(dirname "$0")/timed.sh" "$OUT/$NAME" "$SCENE ($NAME)" \
  xargs -d '\n' -P "$JOBS" -n 1 bash -c 'eval "$1" > /dev/null' _ < "$OUT/$NAME.cmds"
