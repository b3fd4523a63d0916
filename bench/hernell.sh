#!/usr/bin/env bash
# Global light (shade.hernell) figures, all on the CT head: the light update of
# piecewise integration against the exact integration over segment length × SVR
# (experiments/hernell_light.ron), first-order scattering (hernell_scattering.ron),
# the extremes (hernell_extremes.ron), flat blocking (hernell_blocking.ron) and the
# speed-up at twice the CT head's resolution (hernell_scale.ron); on a GPU also the
# light update at 512³ (hernell_512.ron). Writes
# the blocks of docs/hernell.md, on the CPU Vulkan device (lavapipe, 2 threads) unless
# VWB_TEST_GPU=1 (then docs/gpu/hernell.md).
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/experiments.sh hernell_light hernell_scattering hernell_extremes hernell_blocking \
    hernell_scale
if [ "${VWB_TEST_GPU:-0}" = 1 ]; then
    bash bench/experiments.sh hernell_512
fi
