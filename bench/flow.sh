#!/usr/bin/env bash
# Flow study: streamline drift per integrator, LIC time against error, precompute time,
# the storm's LIC image (the benchmark), then LIC lit from its gradients, with DOS and
# with a clip plane, the integrators on the GPU and the two LIC modes (the experiment
# files flow_integrators.ron, flow_arrival_integrators.ron, flow_modes.ron,
# flow_animation.ron, flow_lit.ron, flow_dos.ron and flow_clip.ron,
# into their blocks); writes docs/flow.md and docs/images/storm_lic.png.
# On the CPU Vulkan device (lavapipe, 2 threads) unless VWB_TEST_GPU=1.
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/ignored_test.sh flow_study
bash bench/experiments.sh flow_integrators flow_arrival_integrators flow_modes flow_animation flow_lit flow_dos flow_clip
