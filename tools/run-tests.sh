#!/usr/bin/env bash
# Builds cosim (installing what is missing) and runs the whole test suite:
# once in a Release build, then once more built with AddressSanitizer and
# UndefinedBehaviorSanitizer (skip that pass with COSIM_NO_SANITIZE=1; no
# benchmarks built there: no test runs them), then
# a short run of each fuzz harness (tests/fuzz, clang's libFuzzer under ASan +
# UBSan with LeakSanitizer; COSIM_FUZZ_SECONDS each, default 5: a smoke run that
# keeps the whole under 15 minutes on 2 cores, the corpus replays run in both
# passes above, tests/fuzz/README.md has the longer runs; skip with
# COSIM_NO_FUZZ=1).
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc)
bash tools/setup.sh
echo "== tests (Release)"
ctest --test-dir build --output-on-failure -j"$jobs" --timeout 600
if [ "${COSIM_NO_SANITIZE:-0}" != 1 ]; then
  echo "== tests (AddressSanitizer + UndefinedBehaviorSanitizer)"
  COSIM_BUILD_DIR=build-asan bash tools/setup.sh -DCMAKE_BUILD_TYPE=Debug -DCOSIM_SANITIZE=ON -DCOSIM_BENCH=OFF
  # slow-labelled tests are left to the Release pass
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir build-asan --output-on-failure -j"$jobs" --timeout 900 -LE slow
fi
if [ "${COSIM_NO_FUZZ:-0}" != 1 ]; then
  fuzz_seconds=${COSIM_FUZZ_SECONDS:-5}
  echo "== fuzz (libFuzzer, ASan + UBSan, $fuzz_seconds s per harness)"
  COSIM_BUILD_DIR=build-fuzz COSIM_BUILD_TARGET=fuzz_all bash tools/setup.sh \
    -DCMAKE_C_COMPILER=clang -DCOSIM_FUZZ=ON -DFUZZ_SECONDS="$fuzz_seconds"
  ctest --test-dir build-fuzz --output-on-failure -j"$jobs" -L fuzz
fi
