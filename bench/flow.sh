#!/usr/bin/env bash
# Flow study: streamline drift per integrator, LIC time against error, precompute time,
# the storm's LIC image; writes docs/flow.md and docs/images/storm_lic.png.
set -euo pipefail
cd "$(dirname "$0")/.."
lvp=$(ls /usr/share/vulkan/icd.d/lvp_icd.*.json 2>/dev/null | head -n 1 || true)
if [ "${VWB_TEST_GPU:-0}" != 1 ] && [ -z "${VK_DRIVER_FILES:-}" ] && [ -n "$lvp" ]; then
    export VK_DRIVER_FILES="$lvp"
fi
export LP_NUM_THREADS="${LP_NUM_THREADS:-2}"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
cargo test --workspace --locked --test integration flow_study -- --ignored --nocapture
