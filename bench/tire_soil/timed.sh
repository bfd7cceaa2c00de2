#!/bin/bash
# Runs one benchmark command under the shared benchmark lock and times it:
#   bash bench/tire_soil/timed.sh OUT LABEL COMMAND [ARGS...]
# OUT.log gets the command's output; OUT.time its label (scene: ...), the
# arguments, the load average before and after, the wall time and the exit
# code, which is also this script's. run_paper.sh and run_sand_dbp.sh call it.
set -uo pipefail
OUT=${1:?usage: timed.sh OUT LABEL COMMAND [ARGS...]}
LABEL=${2:?usage: timed.sh OUT LABEL COMMAND [ARGS...]}
shift 2
LOCK=${COSIM_BENCH_LOCK:-/tmp/cosim-bench.lock}
exec 9>"$LOCK"
flock 9
echo "scene: $LABEL" > "$OUT.time"
echo "args: $*" >> "$OUT.time"
echo "load_before: $(cut -d" " -f1-3 /proc/loadavg)" >> "$OUT.time"
t0=$(date +%s.%N)
rc=0
"$@" > "$OUT.log" 2>&1 || rc=$?
t1=$(date +%s.%N)
echo "wall_s: $(echo "$t1 - $t0" | bc)" >> "$OUT.time"
echo "load_after: $(cut -d" " -f1-3 /proc/loadavg)" >> "$OUT.time"
echo "rc: $rc" >> "$OUT.time"
exit $rc
