#!/usr/bin/env bash
# Flow study: streamline drift per integrator, LIC time against error, precompute time,
# the storm's LIC image; writes docs/flow.md and docs/images/storm_lic.png.
# On the CPU Vulkan device (lavapipe, 2 threads) unless VWB_TEST_GPU=1.
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/ignored_test.sh flow_study
