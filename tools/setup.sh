#!/usr/bin/env bash
# Installs what cosim needs from Debian (only what is missing), then
# configures and builds into build/ (or $COSIM_BUILD_DIR). Extra arguments go
# to cmake's configure step, e.g. -DCOSIM_SANITIZE=ON.
set -euo pipefail
cd "$(dirname "$0")/.."
PACKAGES="build-essential cmake pkg-config libzmq3-dev libsodium-dev libhdf5-dev \
libsuitesparse-dev libopenblas-dev libcjson-dev libfftw3-dev \
liggghts libliggghts-dev mpi-default-dev \
python3 python3-numpy python3-scipy python3-h5py python3-matplotlib python3-zmq \
chromium chromium-driver python3-selenium"
# the fuzz build (tests/fuzz) needs clang, its libFuzzer runtime and its OpenMP
case " $* " in *COSIM_FUZZ=ON*) PACKAGES="$PACKAGES clang libclang-rt-14-dev libomp-dev" ;; esac
missing=""
for p in $PACKAGES; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
if [ -n "$missing" ]; then
  echo "setup: installing:$missing"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq $missing >/dev/null
fi
BUILD=${COSIM_BUILD_DIR:-build}
TARGET=${COSIM_BUILD_TARGET:-all} # e.g. fuzz_all: only the fuzz harnesses
cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
cmake --build "$BUILD" -j"$(nproc)" --target "$TARGET" 2>&1 | grep -Ev '^\[|^-- |Consolidate|^$' || true
# the build must have succeeded: fail loudly if not
cmake --build "$BUILD" -j"$(nproc)" --target "$TARGET" >/dev/null
echo "setup: built into $BUILD/bin"
