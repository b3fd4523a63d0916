#!/usr/bin/env python3
"""Per-slice state in one dispatch (issue 23, item 5).

A plugin with per-slice state (shade.dos) needs the slices in order with its state
updated between them. The compute backend ran a slice and then each state update as
separate dispatches, each evaluating the slice's sample; it now runs both in one
dispatch per slice where every state has the eye buffer's resolution
(`Renderer::set_fused_slices`, `VWB_FUSED_SLICES=0` turns it off). This script times,
in interleaved rounds (the order reversed every other round):

- two dispatches per slice (`VWB_FUSED_SLICES=0`), the previous default;
- one dispatch per slice (the default);
- with `--tile-vwb BUILD`: a build of commit 9df58ca, whose occlusion taps filter the
  previous state from a workgroup tile (the halo of 4 texels loaded once per
  workgroup, `workgroupBarrier`) instead of sampling the texture (rejected);
- the raster backend (a render pass and an update dispatch per slice);

and each image's difference from the two-dispatch image, then the fixed cost of a
slice at 32 × 32 (frame time / slices), which bounds what fewer dispatches can save.
Writes the `slice-state` block of docs/perf.md.

    python3 bench/slice_state.py [--vwb target/release/vwb] [--tile-vwb OTHER/vwb]
        [--rounds 2] [--frames 1] [--size 512x512]

Needs numpy and pillow (`pip install numpy pillow`; not part of the test set-up).
"""

import shlex
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

import perf
from doclib import bench_parser, publish, vwb_env
from raster_options import rgb

PRESETS = ["presets/demo_dos.ron", "presets/ct_dos.ron"]
TWO = {"VWB_FUSED_SLICES": "0"}


def main():
    ap = bench_parser(__doc__, "slice-state", 1, 2, "the demo's and the CT head's DOS")
    ap.add_argument("--tile-vwb", help="a build of 9df58ca (state tile in workgroup memory)")
    a = ap.parse_args()
    presets = a.preset or PRESETS
    # (label, binary, backend, extra environment)
    variants = [("two dispatches per slice", a.vwb, "compute", TWO),
                ("one dispatch per slice (default)", a.vwb, "compute", {})]
    if a.tile_vwb:
        variants.append(("one dispatch, state tile in workgroup memory (9df58ca)", a.tile_vwb, "compute", {}))
    variants.append(("raster (pass + update per slice)", a.vwb, "raster", {}))
    tmp = Path(tempfile.gettempdir())
    times = {(p, v[0]): [] for p in presets for v in variants}
    small = {(p, v[0]): [] for p in presets for v in variants[:2]}
    slices = {}
    adapter = "?"
    for r in range(a.rounds):
        order = list(enumerate(variants))
        if r % 2:
            order.reverse()
        for p in presets:
            for i, (label, vwb, backend, env_extra) in order:
                env = dict(vwb_env(a.gpu), **env_extra)
                res = perf.run(vwb, p, backend, a.size, a.frames, env)
                adapter = res["adapter"]
                slices[p] = res["slices"]
                times[(p, label)].append((res["gpu"] or res["wall"])[0])
                keep = tmp / f"vwb-ss-{Path(p).stem}-{i}.png"
                keep.write_bytes((tmp / "vwb-perf.png").read_bytes())
                if i < 2:
                    res = perf.run(vwb, p, backend, "32x32", 3, env)
                    small[(p, label)].append((res["gpu"] or res["wall"])[0] / max(res["slices"], 1))
    rows = ["| preset | slices | variant | ms | ratio to two dispatches | RMS vs two-dispatch image (8-bit) "
            "| largest difference |",
            "|---|---:|---|---:|---:|---:|---:|"]
    for p in presets:
        base = statistics.median(times[(p, variants[0][0])])
        ref = rgb(tmp / f"vwb-ss-{Path(p).stem}-0.png")
        for i, (label, *_rest) in enumerate(variants):
            m = statistics.median(times[(p, label)])
            d = rgb(tmp / f"vwb-ss-{Path(p).stem}-{i}.png") - ref
            rows.append(f"| `{Path(p).stem}` | {slices[p]} | {label} | {perf.ms(m)} | {m / base:.2f} "
                        f"| {float(np.sqrt(np.mean(d ** 2))):.2f} | {int(np.abs(d).max())} |")
    rows += ["", "Fixed cost of a slice: frame time / slices at 32 × 32 (ms per slice), where the work is "
             "negligible:", "",
             "| preset | two dispatches | one dispatch |", "|---|---:|---:|"]
    for p in presets:
        two, one = (statistics.median(small[(p, v[0])]) for v in variants[:2])
        rows.append(f"| `{Path(p).stem}` | {two:.3f} | {one:.3f} |")
    publish(shlex.join(["python3", "bench/slice_state.py", *sys.argv[1:]]),
            f"{a.size}, median over {a.rounds} interleaved rounds of each render's median of "
            f"{a.frames} frame(s) after 2 warm-up frames (GPU ms).", adapter, a.gpu, rows, a.block,
            a.print_only)

if __name__ == "__main__":
    main()
