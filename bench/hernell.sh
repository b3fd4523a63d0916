#!/usr/bin/env bash
# Global light (shade.hernell) figures: piecewise against exact integration over
# segment length × SVR with the time of each update level, scattering refinement
# costs, on the CT head, then the extremes (experiments/hernell_extremes.ron);
# writes docs/hernell.md. On the CPU Vulkan device (lavapipe, 2 threads) unless
# VWB_TEST_GPU=1 (then docs/gpu/hernell.md).
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/ignored_test.sh hernell_benchmark
bash bench/experiments.sh hernell_extremes
