#!/usr/bin/env bash
# Global light (shade.hernell) figures, all on the CT head: the light update of
# piecewise integration against the exact integration over segment length × SVR
# (experiments/hernell_light.ron), first-order scattering (hernell_scattering.ron),
# the extremes (hernell_extremes.ron) and flat blocking (hernell_blocking.ron); on a
# GPU also the light update at 512³ (the ignored test hernell_512_benchmark). Writes
# the blocks of docs/hernell.md, on the CPU Vulkan device (lavapipe, 2 threads) unless
# VWB_TEST_GPU=1 (then docs/gpu/hernell.md).
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/experiments.sh hernell_light hernell_scattering hernell_extremes hernell_blocking
if [ "${VWB_TEST_GPU:-0}" = 1 ]; then
    bash bench/ignored_test.sh hernell_512_benchmark
fi
