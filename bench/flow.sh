#!/usr/bin/env bash
# Flow study: streamline drift per integrator, LIC time against error (the f64 twin's
# tables), the storm's LIC image, then the experiment files into their blocks: the
# LIC pre-pass at 128³ and 256³ (flow_precompute.ron, flow_precompute_256.ron), the
# integrators on the GPU, the two LIC modes, LIC lit from its gradients, with DOS and
# with a clip plane (flow_integrators.ron, flow_arrival_integrators.ron, flow_modes.ron,
# flow_animation.ron, flow_lit.ron, flow_dos.ron and flow_clip.ron); writes docs/flow.md
# and docs/images/storm_lic.png.
# On the CPU Vulkan device (lavapipe, 2 threads) unless VWB_TEST_GPU=1.
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/ignored_test.sh flow_study
bash bench/experiments.sh flow_precompute flow_precompute_256 flow_integrators flow_arrival_integrators flow_modes flow_animation flow_lit flow_dos flow_clip
