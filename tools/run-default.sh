#!/usr/bin/env bash
# Builds cosim (installing what is missing), runs the default scene and plots
# its time series (PNGs in <output dir>/plots).
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
log=$(mktemp)
trap 'rm -f "$log"' EXIT
build/bin/cosim run configs/default.json "$@" | tee "$log"
results=$(sed -n 's/^results: \([^ ]*\) .*/\1/p' "$log")
if [ -n "$results" ] && [ -f "$results" ]; then
  /usr/bin/python3 tools/plot_run.py "$results"
fi
