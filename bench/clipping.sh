#!/usr/bin/env bash
# Clipping figures, from experiment files into their blocks: docs/clipping.md
# (clip.shapes: the DOS consistency gate, also with a box mesh, clip_dos; a cut through
# matter and shading at the cut against the cropped phantom, clip_cut; GPU against twin
# per mode, clip_twin; the overhead of 1, 4 and 16 planes, clip_planes; skipping
# clipped bricks, clip_skipping) and docs/clip_mesh.md (clip.mesh: GPU against twin,
# clip_mesh_twin; frame cost and skipping, clip_mesh_cost; the voxelised sphere against
# the analytic one, clip_mesh_accuracy); then the mesh pass's section of
# docs/clip_mesh.md (voxelisation time, reruns while orbiting: the ignored test
# clip_mesh_benchmark). On the CPU Vulkan device (lavapipe, 2 threads) unless
# VWB_TEST_GPU=1.
set -euo pipefail
cd "$(dirname "$0")/.."
bash bench/experiments.sh clip_dos clip_cut clip_twin clip_planes clip_skipping \
    clip_mesh_twin clip_mesh_cost clip_mesh_accuracy
bash bench/ignored_test.sh clip_mesh_benchmark
