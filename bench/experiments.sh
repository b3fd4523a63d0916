#!/usr/bin/env bash
# Runs the named experiment files (experiments/NAME.ron) with the debug `vwb`, each
# into reports/NAME and its doc block, on the CPU Vulkan device (lavapipe, 2 threads)
# unless VWB_TEST_GPU=1. Used by bench/clipping.sh and bench/flow.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
lvp=$(ls /usr/share/vulkan/icd.d/lvp_icd.*.json 2>/dev/null | head -n 1 || true)
if [ "${VWB_TEST_GPU:-0}" != 1 ] && [ -z "${VK_DRIVER_FILES:-}" ] && [ -n "$lvp" ]; then
    export VK_DRIVER_FILES="$lvp"
fi
export LP_NUM_THREADS="${LP_NUM_THREADS:-2}"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
cargo build --locked
for name in "$@"; do
    ./target/debug/vwb run "experiments/$name.ron" -o "reports/$name"
done
