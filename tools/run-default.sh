#!/usr/bin/env bash
# Builds cosim (installing what is missing) and runs the default scene.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
exec build/bin/cosim run configs/default.json "$@"
