#!/usr/bin/env bash
# Runs the named experiment files (experiments/NAME.ron) with the debug `vwb`, each
# into reports/NAME and its doc block, on the CPU Vulkan device (lavapipe, 2 threads)
# unless VWB_TEST_GPU=1. Used by bench/clipping.sh and bench/flow.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
source bench/lavapipe.sh
cargo build --locked
for name in "$@"; do
    ./target/debug/vwb run "experiments/$name.ron" -o "reports/$name"
done
