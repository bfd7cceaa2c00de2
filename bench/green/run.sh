#!/bin/sh
# bench/green/run.sh BUILD_DIR OUT_DIR — makes road, springs and Green's
# functions with cosim_green and the pictures of bench/results/green_springs.md.
set -e
B=${1:-build-green}
O=${2:-bench/results}
T=$(mktemp -d)
G=$B/bin/cosim_green
$G road --out $T/road.h5 --points 2000 --pitch 1e-5 --hurst 0.8 --rms 1e-4 \
        --lambda-short 5e-5 --lambda-long 1e-2 --seed 1 2> $T/road.log
$G springs --road $T/road.h5 --elements 20x20 --out $T/springs.h5 2> $T/springs.log
/usr/bin/time -f "%e s wall, %M kB" $G green --model dynamic --elements 20x20 --size 1e-3 \
        --thickness 0.01 --Q 256 --rate 51200 --out $T/green.h5 \
        --out-point $T/green_point.h5 2> $T/green.log || true
$G green --model dynamic --elements 4x4 --Q 1024 --out $T/green_q1024.h5 2> $T/green_q1024.log || true
$G green --model dynamic --elements 4x4 --Q 256 --pad 120 --out $T/green_pad120.h5 2> $T/green_pad.log || true
$G green --model dynamic --elements 4x4 --Q 256 --out $T/green_4.h5 2> $T/green_4.log || true
$G green --model layer --elements 20x20 --out $T/layer.h5 2> /dev/null
$G green --model love --elements 20x20 --out $T/love.h5 2> /dev/null
$B/bin/bench_green_punch > $T/punch.txt
cat $T/*.log
/usr/bin/python3 bench/green/plots.py $T $O
echo "work files in $T"
