#!/usr/bin/env bash
# Runs one ignored benchmark test of the integration suite (its name is the first
# argument) on the CPU Vulkan device (lavapipe, 2 threads) unless VWB_TEST_GPU=1.
# Used by bench/atlas.sh, bench/ui.sh, bench/clipping.sh and bench/flow.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
source bench/lavapipe.sh
cargo test --workspace --locked --test integration "$1" -- --ignored --nocapture
