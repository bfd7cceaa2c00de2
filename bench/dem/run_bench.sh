#!/bin/sh
# DEM benchmarks against Debian's LIGGGHTS (installed here if missing), then
# plots and tables: bench/results/dem.md, bench/results/dem_*.png.
# usage: bench/dem/run_bench.sh [BUILD_DIR] [parts...]   (parts: impact beds wp stability)
set -e
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build-dem}
[ $# -gt 0 ] && shift
if ! command -v liggghts >/dev/null 2>&1; then
  apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y liggghts
fi
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j2 --target bench_dem bench_impact dem_server
/usr/bin/python3 "$root/bench/dem/run_bench.py" "$build/bin" "$root/bench/results" "$@"
/usr/bin/python3 "$root/bench/dem/plot_dem.py" "$root/bench/results"
