#!/usr/bin/env bash
# Clipping figures, from experiment files into their blocks: docs/clipping.md
# (clip.shapes: the DOS consistency gate, also with a box mesh, clip_dos; a cut through
# matter and shading at the cut against the cropped phantom, clip_cut; GPU against twin
# per mode, clip_twin; the overhead of 1, 4 and 16 planes, clip_planes; skipping
# clipped bricks, clip_skipping) and docs/clip_mesh.md (clip.mesh: GPU against twin,
# clip_mesh_twin; frame cost and skipping, clip_mesh_cost; the voxelised sphere against
# the analytic one, clip_mesh_accuracy; the mesh pass's voxelisation time, the probe
# clip_mesh_pass; a camera orbit builds the grid once, clip_mesh_orbit). On the CPU
# Vulkan device (lavapipe, 2 threads) unless VWB_TEST_GPU=1.
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/experiments.sh clip_dos clip_cut clip_twin clip_planes clip_skipping \
    clip_mesh_twin clip_mesh_cost clip_mesh_accuracy clip_mesh_pass clip_mesh_orbit
