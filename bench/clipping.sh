#!/usr/bin/env bash
# Clipping figures (clip.shapes): the DOS consistency gate, shading at the cut and GPU
# against twin per mode (the benchmark), then the overhead of 1, 4 and 16 planes and
# the speed-up from skipping clipped bricks (the experiment files clip_planes.ron and
# clip_skipping.ron, into their blocks); writes docs/clipping.md; and the clip.mesh
# figures (docs/clip_mesh.md, its accuracy against the analytic sphere from
# clip_mesh_accuracy.ron). On the CPU Vulkan device (lavapipe, 2 threads) unless
# VWB_TEST_GPU=1.
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/ignored_test.sh clipping_benchmark
bash bench/ignored_test.sh clip_mesh_benchmark
bash bench/experiments.sh clip_planes clip_skipping clip_mesh_accuracy
