#!/usr/bin/env bash
# Bricking figures: the CT head split at lowered 3D-texture limits against one texture
# (time and ΔE*uv), and a 512×512×2100 int16 volume on the adapter's own limit; writes
# the generated section of docs/scale.md and docs/images/tall_volume.png. On the CPU
# Vulkan device (lavapipe, 2 threads) unless VWB_TEST_GPU=1. Needs about 8 GB of memory.
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/ignored_test.sh bricks_benchmark
