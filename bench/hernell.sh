#!/usr/bin/env bash
# Global light (shade.hernell) figures, all on the CT head: the light update of
# piecewise integration against the exact integration over segment length × SVR
# (experiments/hernell_light.ron), first-order scattering (hernell_scattering.ron) and
# the extremes (hernell_extremes.ron); on a GPU also the light update at 512³ (the
# ignored test hernell_512_benchmark). Writes the blocks of docs/hernell.md, on the CPU
# Vulkan device (lavapipe, 2 threads) unless VWB_TEST_GPU=1 (then docs/gpu/hernell.md).
# Flat blocking has its own: bash bench/ignored_test.sh hernell_blocking_benchmark.
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/experiments.sh hernell_light hernell_scattering hernell_extremes
if [ "${VWB_TEST_GPU:-0}" = 1 ]; then
    bash bench/ignored_test.sh hernell_512_benchmark
fi
