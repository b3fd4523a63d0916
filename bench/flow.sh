#!/usr/bin/env bash
# The flow study (docs/flow.md): every experiment file that writes into it, each into
# reports/NAME and its doc block. The f64 twin's own numerics are the plugins' probes
# (no GPU): streamline drift by integrator and step (flow_drift.ron), the twin LIC's
# time against error (flow_twin_lic.ron), arrival times against the exact ones
# (flow_arrival_rotation.ron). Then the GPU's: the LIC integrators, the pre-pass at 128³
# and 256³, the two LIC modes and the animated phase, the output sensitivity, LIC lit, with DOS and clipped,
# flow.arrival's pre-pass against its twin, its integrators and playing its time, and
# the storm (its images into docs/images/). flow_arrival_prepass_large.ron and
# flow_output_sensitivity_large.ron are a GPU's (bench/gpu.sh). On the CPU Vulkan device (lavapipe, 2 threads) unless VWB_TEST_GPU=1.
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/experiments.sh flow_drift flow_twin_lic flow_arrival_rotation \
    flow_integrators flow_precompute flow_precompute_256 flow_modes flow_animation \
    flow_output_sensitivity \
    flow_lit flow_dos flow_clip flow_arrival_prepass flow_arrival_integrators \
    flow_arrival_play flow_storm flow_storm_time_surfaces
