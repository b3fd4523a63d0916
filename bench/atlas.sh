#!/usr/bin/env bash
# Many views in one submission: an atlas of 64 TF variants against 64 single renders
# (each updating the stack, rendering and reading back), at 64² and 128²; writes
# docs/atlas_bench.json. On the CPU Vulkan device (lavapipe, 2 threads) unless
# VWB_TEST_GPU=1.
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/ignored_test.sh atlas_benchmark
cat docs/atlas_bench.json
