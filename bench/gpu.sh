#!/usr/bin/env bash
# The GPU figures, on a machine with a GPU and without a Rust toolchain: runs the
# release `vwb` and the integration-test binary built on another machine (same
# x86-64 Linux), each step under a time limit, and copies what they write to OUT.
#
#   bash bench/gpu.sh VWB INTEGRATION DATA_DIR OUT
#   GPU_STEPS="perf scaling presets suite" bash bench/gpu.sh ...   # some steps only
#
# VWB: target/release/vwb; INTEGRATION: the binary `cargo test --locked --test
# integration --no-run` prints; DATA_DIR: the sample data (VWB_DATA_DIR). Writes to OUT:
#   perf.md            docs/perf.md with its `foundation-gpu` block (bench/perf.py --gpu)
#   gpu-perf.md        docs/gpu/perf.md: the `foundation-gpu-1024` block (the same at
#                      1024²) and the `scaling` block (bench/scaling.py --gpu)
#   presets.log        DOS and shaded presets, both backends, 512² (`vwb render --timings`)
#   backends.log       step `backends` (not in the default steps): DOS on both backends
#                      and at half buffer resolution, raster with 1 and 8 slices per
#                      polygon against compute, with and without early termination
#   gpu-docs.tar       docs/gpu/: flow.md and hernell.md (the blocks of the
#                      experiment files hernell_512,
#                      flow_precompute_256, flow_arrival_prepass_large,
#                      flow_output_sensitivity_large, flow_modes,
#                      search_gallery, search_gallery_large (into search.md),
#                      flow_animation, hernell_light,
#                      hernell_scattering, hernell_extremes and hernell_blocking),
#                      perf.md (experiments/volume_format.ron), clipping.md and
#                      clip_mesh.md (clip_planes, clip_skipping, clip_mesh_cost: the
#                      frame cost of planes and meshes, which the docs leave open)
#   suite.log          the integration suite on the GPU (a check, not a figure)
#   ab_tables16_*.json, accuracy_tables16.json
#                      classification tables in rgba16float against rgba32float
#                      (bench/table_formats.py; step `tables`, not in the default
#                      steps: about 5 minutes)
#   *.log              each step's output
# The integration binary finds the repository through the path it was built in
# (CARGO_MANIFEST_DIR); run this from a checkout at that path or link it there.
set -uo pipefail
cd "$(dirname "$0")/.."
vwb=$(realpath "$1") integration=$(realpath "$2") data=$(realpath "$3") out=$(realpath "$4")
export VWB_DATA_DIR="$data" XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}" VWB_TEST_GPU=1
unset LP_NUM_THREADS  # VK_DRIVER_FILES: the caller's (the GPU's ICD where the loader does not find it)
mkdir -p "$out"
step() { # name limit_s command...
    local name=$1 limit=$2; shift 2
    local t0=$SECONDS
    timeout "$limit" "$@" >"$out/$name.log" 2>&1
    echo "$name: rc=$? in $((SECONDS - t0)) s" | tee -a "$out/steps.txt"
}
steps=" ${GPU_STEPS:-perf scaling presets experiments suite} "
want() { [[ $steps == *" $1 "* ]]; }
presets() {
    for p in ct_head ct_shade_phong ct_dos ct_dos_chromatic demo_dos nuclei_dos; do
        for b in compute raster; do
            echo "== $p $b"
            "$vwb" render --preset "presets/$p.ron" --size 512x512 --backend $b --timings \
                --frames 10 -o "/tmp/vwb-gpu-$p-$b.png" 2>&1 | grep -E "adapter|gpu_ms|wall_ms"
        done
    done
}
backends() { # GPU ms of the DOS presets on both backends (and a half-resolution occlusion
    # buffer), and of four presets on compute against raster with a polygon per slice
    # and with 8 slices per polygon, without and with early termination 0.99
    r() {
        local l=$1
        shift
        printf '%s\t' "$l"
        "$vwb" render --size 512x512 --timings --frames 10 -o /tmp/vwb-gpu-b.png "$@" 2>&1 |
            grep -E gpu_ms | tr '\n' ' '
        echo
    }
    for p in ct_dos ct_dos_chromatic demo_dos nuclei_dos; do
        for b in compute raster; do r "$p $b" --preset "presets/$p.ron" --backend $b; done
    done
    sed 's/"ambient": 0.15}/"ambient": 0.15, "buffer_scale": "0.5"}/' presets/ct_dos.ron \
        >/tmp/vwb-gpu-ct_dos_half.ron
    for b in compute raster; do r "ct_dos buffer 0.5 $b" --preset /tmp/vwb-gpu-ct_dos_half.ron --backend $b; done
    for p in ct_shade_none ct_shade_phong demo nuclei; do
        for et in none 0.99; do
            local e=()
            [ $et != none ] && e=(--early-termination $et)
            r "$p compute et=$et" --preset "presets/$p.ron" --backend compute "${e[@]}"
            for n in 1 8; do
                r "$p raster$n et=$et" --preset "presets/$p.ron" --backend raster \
                    --slices-per-proxy $n "${e[@]}"
            done
        done
    done
}
if want perf; then
    step perf 90 python3 bench/perf.py --vwb "$vwb" --gpu --block foundation-gpu --frames 20
    step perf1024 90 python3 bench/perf.py --vwb "$vwb" --gpu --size 1024x1024 \
        --block foundation-gpu-1024 --frames 20 --doc docs/gpu/perf.md
    cp docs/perf.md "$out/perf.md"
fi
want scaling && step scaling 200 python3 bench/scaling.py --vwb "$vwb" --gpu --doc docs/gpu/perf.md
want perf || want scaling && cp docs/gpu/perf.md "$out/gpu-perf.md"
export -f presets backends; export vwb
want presets && step presets 120 bash -c presets
want backends && step backends 120 bash -c backends
want experiments && step experiments 540 "$vwb" run experiments/volume_format.ron experiments/flow_modes.ron \
    experiments/flow_precompute_256.ron experiments/flow_arrival_prepass_large.ron \
    experiments/search_gallery.ron experiments/search_gallery_large.ron \
    experiments/flow_output_sensitivity_large.ron experiments/hernell_512.ron \
    experiments/flow_animation.ron experiments/hernell_light.ron \
    experiments/hernell_scattering.ron experiments/hernell_extremes.ron \
    experiments/hernell_blocking.ron experiments/clip_planes.ron \
    experiments/clip_skipping.ron experiments/clip_mesh_cost.ron
want experiments && tar cf "$out/gpu-docs.tar" docs/gpu 2>/dev/null
want tables && step tables 420 python3 bench/table_formats.py --vwb "$vwb" --gpu -o "$out"
if want suite; then
    step suite 150 "$integration" --test-threads=8
    grep -E "^test result|FAILED|panicked" "$out/suite.log" | head -40 >>"$out/steps.txt"
fi
