#!/usr/bin/env bash
# UI frame time of the workbench window with the CT head while a TF point is dragged
# (preview quality), for several preview settings; writes docs/ui_bench.json.
# On the CPU Vulkan device (lavapipe, 2 threads) unless VWB_TEST_GPU=1.
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/ignored_test.sh ui_frame_time_benchmark
cat docs/ui_bench.json
