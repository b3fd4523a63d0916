#!/usr/bin/env bash
# Clipping figures (clip.shapes): overhead of 1, 4 and 16 planes, the speed-up from
# skipping clipped bricks, the DOS consistency gate and GPU against twin per mode;
# writes docs/clipping.md; and the clip.mesh figures (docs/clip_mesh.md). On the CPU Vulkan device (lavapipe, 2 threads) unless
# VWB_TEST_GPU=1.
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/ignored_test.sh clipping_benchmark
bash bench/ignored_test.sh clip_mesh_benchmark
