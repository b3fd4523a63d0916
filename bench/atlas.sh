#!/usr/bin/env bash
# Many views in one submission: an atlas of 64 TF variants against 64 single renders
# (each updating the stack, rendering and reading back), at 64² and 128²; writes
# docs/atlas_bench.json. On the CPU Vulkan device (lavapipe, 2 threads) unless
# VWB_TEST_GPU=1.
set -euo pipefail
cd "$(dirname "$0")/.."
lvp=$(ls /usr/share/vulkan/icd.d/lvp_icd.*.json 2>/dev/null | head -n 1 || true)
if [ "${VWB_TEST_GPU:-0}" != 1 ] && [ -z "${VK_DRIVER_FILES:-}" ] && [ -n "$lvp" ]; then
    export VK_DRIVER_FILES="$lvp"
fi
export LP_NUM_THREADS="${LP_NUM_THREADS:-2}"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
cargo test --workspace --locked --test integration atlas_benchmark -- --ignored --nocapture
cat docs/atlas_bench.json
