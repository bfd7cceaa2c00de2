#!/bin/sh
# Soil parameters of the tyre scenes' grains by virtual tests with dem_server's
# library (terra/README.md), their fits, and the terramechanics reference curve.
# Records in bench/results/terra/, tables and PNGs: bench/results/terra.md.
#
# usage: bench/terra/run_terra.sh [BUILD_DIR] [stage...]
#   stages: deep paper fine coarse checks fit (default: all, in that order) on
#   configs/default.json's 5 MPa grains; scene20: the paper scene's own grains
#   (configs/tire_soil_paper.json: 20 MPa, its pair friction), plates on its bed
#   depth (38 mm on the floor), fine shear box, fit and reference curves at 80 N;
#   sand: configs/tire_soil_sand.json's calibrated grains (sandplates, sandshear,
#   sandfit; two may run at once, one per core): plates on its 0.25 m bed depth to the
#   rated load's 150 kPa, the 20 cm shear box at 10-50 kPa, one packing: its fit
#   terra/soil_sand_s1.json, curves at 1 kN and 4042 N, plots and tables (plot_terra.py)
# Runs that already have their record are skipped (delete it to redo).
# COSIM_LOCK=FILE wraps every DEM run in `flock FILE` (machines shared with
# other heavy jobs); THREADS (default 1: on a busy machine OpenMP threads wait for each other) sets the DEM's OpenMP threads.
set -e
root=$(cd "$(dirname "$0")/../.." && pwd)
build=$(cd "${1:-$root/build}" && pwd)
[ $# -gt 0 ] && shift
stages=${*:-deep paper fine coarse checks fit}
cd "$root" # the records and fits name the scene and records by these relative paths
out=bench/results/terra
scene=configs/default.json
sand=configs/tire_soil_sand.json
threads=${THREADS:-1}
terra=$build/bin/cosim_terra
mkdir -p "$out"
cmake --build "$build" -j2 --target cosim_terra_cli >/dev/null

run() { # run OUTPUT ARGS...: one virtual test unless its record exists
  o=$1; shift
  [ -s "$o" ] && return 0
  echo "== $(basename "$o")"
  if [ -n "$COSIM_LOCK" ]; then flock "$COSIM_LOCK" "$terra" "$@" --threads "$threads" --out "$o.tmp"
  else "$terra" "$@" --threads "$threads" --out "$o.tmp"; fi
  mv "$o.tmp" "$o"
}

# The bevameter: three square plates (the largest = the tyre's width 0.165 m),
# container walls 1.5-2.5 plate widths away, 0.02 m/s, three packings.
plates() { # plates BED DEPTH_FACTOR ZMAX
  for seed in 1 2 3; do
    for bc in 0.060:0.36 0.110:0.50 0.165:0.66; do
      b=${bc%:*}; L=${bc#*:}
      run "$out/plate_$1_b${b}_s$seed.csv" plate "$scene" --width "$b" --container "$L" \
        --depth-factor "$2" --speed 0.02 --zmax "$3" --seed "$seed"
    done
  done
}

# The shear box at four normal stresses, three packings: the deep bed's top
# (the 6.9 +- 0.345 and 7.8 mm layers) and the paper bed's 15.6 mm grains in a
# box scaled with the grain (30 x 30 x 15 grain diameters, same inertial number).
shears() { # shears SOIL DMIN DMAX LENGTH HEIGHT SPEED JMAX DJ
  for seed in 1 2 3; do
    for sig in 2500 5000 10000 20000; do
      run "$out/shear_$1_sig${sig}_s$seed.csv" shear "$scene" --sigma "$sig" --dmin "$2" --dmax "$3" \
        --length "$4" --box-width "$4" --height "$5" --speed "$6" --jmax "$7" --dj "$8" --seed "$seed"
    done
  done
}

for st in $stages; do
  case $st in
  deep) plates deep 4 0.045 ;;
  paper) plates paper 1 0.025 ;;
  fine) shears fine 0.006555 0.0078 0.2 0.1 0.02 0.03 0.00025 ;;
  coarse) shears coarse 0.0156 0.0156 0.4 0.2 0.04 0.06 0.0005 ;;
  checks)
    # quasi-static: half the speed; container: walls 2 widths away; stiffness: 2 E
    run "$out/check_plate_deep_b0.110_half_speed.csv" plate "$scene" --width 0.110 --container 0.50 \
      --depth-factor 4 --speed 0.01 --zmax 0.045 --seed 1
    run "$out/check_plate_deep_b0.165_big_box.csv" plate "$scene" --width 0.165 --container 0.825 \
      --depth-factor 4 --speed 0.02 --zmax 0.045 --seed 1
    stiff=$out/check_scene_2E.json
    /usr/bin/python3 -c "import json,sys; s=json.load(open(sys.argv[1])); \
m=s['processes']['dem']['materials'][0]; m['E']*=2; json.dump(s,open(sys.argv[2],'w'),indent=1)" "$scene" "$stiff"
    run "$out/check_plate_deep_b0.110_2E.csv" plate "$stiff" --width 0.110 --container 0.50 \
      --depth-factor 4 --speed 0.02 --zmax 0.045 --seed 1
    run "$out/check_shear_fine_sig5000_half_speed.csv" shear "$scene" --sigma 5000 --dmin 0.006555 \
      --dmax 0.0078 --length 0.2 --box-width 0.2 --height 0.1 --speed 0.01 --jmax 0.03 --dj 0.00025 --seed 1
    ;;
  fit)
    for bed in deep:fine paper:coarse; do
      b=${bed%%:*}; rest=${bed#*:}; soil=${rest%:*}
      for seed in 1 2 3; do # packing k: its plates and its shear box
        sh_seed=$seed
        "$terra" fit --plate "$out/plate_${b}_b0.060_s$seed.csv" --plate "$out/plate_${b}_b0.110_s$seed.csv" \
          --plate "$out/plate_${b}_b0.165_s$seed.csv" \
          --shear "$out/shear_${soil}_sig2500_s$sh_seed.csv" --shear "$out/shear_${soil}_sig5000_s$sh_seed.csv" \
          --shear "$out/shear_${soil}_sig10000_s$sh_seed.csv" --shear "$out/shear_${soil}_sig20000_s$sh_seed.csv" \
          --out "$out/soil_${b}_s$seed.json"
      done
      "$terra" combine "$out/soil_${b}_s1.json" "$out/soil_${b}_s2.json" "$out/soil_${b}_s3.json" \
        --out "$root/bench/results/terra_params_$b.json"
      for W in 100 250 500; do
        "$terra" curve --params "$root/bench/results/terra_params_$b.json" --radius 0.272 --width 0.165 \
          --load "$W" --slips 0:0.3:0.01 --out "$root/bench/results/terra_reference_${b}_W$W.csv"
      done
    done
    /usr/bin/python3 "$root/bench/terra/plot_terra.py" "$root/bench/results"
    ;;
  scene20)
    # the paper scene's grains, bed and plate (tread) material; one packing
    p20=$root/configs/tire_soil_paper.json
    # two widths, to 12 mm: deeper, the 20 MPa grains of the 38 mm bed are pressed into the
    # floor (b = 0.06 m: 21 kPa at 7.5 mm, 282 kPa at 15 mm and a bottom grain at half its
    # radius), and the 0.165 m plate does that at 5 mm (38 kPa): on this bed the floor carries
    # a plate, so the fit's k_c, k_phi, n are effective values of the bed, floor included
    for bc in 0.060:0.36 0.110:0.50; do
      b=${bc%:*}; L=${bc#*:}
      run "$out/plate_paper20_b${b}_s1.csv" plate "$p20" --width "$b" --container "$L" \
        --depth-factor 1 --speed 0.02 --zmax 0.012 --seed 1
    done
    for sig in 2500 5000 10000 20000; do
      run "$out/shear_fine20_sig${sig}_s1.csv" shear "$p20" --sigma "$sig" --dmin 0.006555 \
        --dmax 0.0078 --length 0.2 --box-width 0.2 --height 0.1 --speed 0.02 --jmax 0.03 \
        --dj 0.00025 --seed 1
    done
    "$terra" fit --plate "$out/plate_paper20_b0.060_s1.csv" --plate "$out/plate_paper20_b0.110_s1.csv" \
      --shear "$out/shear_fine20_sig2500_s1.csv" --shear "$out/shear_fine20_sig5000_s1.csv" \
      --shear "$out/shear_fine20_sig10000_s1.csv" --shear "$out/shear_fine20_sig20000_s1.csv" \
      --out "$root/bench/results/tire_soil_terra_params_paper20.json"
    "$terra" curve --params "$root/bench/results/tire_soil_terra_params_paper20.json" --radius 0.272 \
      --width 0.165 --load 80 --slips 0:0.3:0.01 --out "$root/bench/results/tire_soil_terra_reference_paper20_W80.csv"
    ;;
  sand) "$root/bench/terra/run_terra.sh" "$build" sandplates sandshear sandfit ;;
  sandplates)
    # the scene's bed (depth factor 8: 0.25 m), prepared as the scene prepares it (settled
    # with friction 0.6, then its laws), the plate carrying the tread's contact law; to
    # 150 kPa (the mean contact pressure at the rated load) at 0.05 m/s (quasi-static:
    # inertial number ~1e-3, bench/results/sand_calibration.md); settled as long as the
    # scene settles its bed (settle_max_steps 90 000: the default 40 000 steps are 0.26 s at
    # the 6.47 us step of these grains, and a 0.25 m bed still moves then)
    for bc in 0.060:0.30 0.110:0.44; do
      b=${bc%:*}; L=${bc#*:}
      run "$out/plate_sand_b${b}_s1.csv" plate "$sand" --width "$b" --container "$L" \
        --depth-factor 8 --speed 0.05 --zmax 0.05 --dz 0.001 --pmax 150000 --prep-friction 0.6 --seed 1 \
        --settle-steps 90000
    done
    ;;
  sandshear)
    # the 20 cm box of the calibration, 10-50 kPa: the plane's stress then reaches
    # 18-80 kPa, the tyre's at 1 kN (the rated load's ~140 kPa: not measured yet)
    for sj in 10000:0.015 20000:0.015 50000:0.02; do
      sig=${sj%:*}; j=${sj#*:}
      run "$out/shear_sand_sig${sig}_s1.csv" shear "$sand" --sigma "$sig" --dmin 0.006555 \
        --dmax 0.0078 --length 0.2 --box-width 0.2 --height 0.1 --speed 0.02 --jmax "$j" \
        --dj 0.00025 --prep-friction 0.6 --seed 1
    done
    ;;
  sandfit)
    # one packing (seed 1): its fit is the parameter set (combine needs two or more)
    "$terra" fit --plate "$out/plate_sand_b0.060_s1.csv" --plate "$out/plate_sand_b0.110_s1.csv" \
      --shear "$out/shear_sand_sig10000_s1.csv" --shear "$out/shear_sand_sig20000_s1.csv" \
      --shear "$out/shear_sand_sig50000_s1.csv" --out "$out/soil_sand_s1.json"
    for W in 1000 4042; do
      "$terra" curve --params "$out/soil_sand_s1.json" --radius 0.272 --width 0.165 --load "$W" \
        --slips 0:0.4:0.01 --out "$root/bench/results/terra_reference_sand_W$W.csv"
    done
    /usr/bin/python3 "$root/bench/terra/plot_terra.py" "$root/bench/results" sand
    ;;
  *) echo "unknown stage '$st'" >&2; exit 1 ;;
  esac
done
