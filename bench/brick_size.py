#!/usr/bin/env python3
"""Brick size of empty-space skipping (issue 23, item 1).

The compute backend's loop jumps over the slices a ray spends in a brick that cannot be
visible: one step per empty brick (a sample position, one occupancy load and the
brick's exit), whatever the brick's length along the ray, which is the cost a DDA over
the brick grid would have. The brick's side trades how much empty space the grid finds
(smaller bricks fit the matter tighter) against how many steps a ray takes through it
(larger bricks, fewer steps). This script times the compute backend with skipping off
and with bricks of 4, 8 (the default), 16 and 32 voxels (`VWB_SKIP_BRICK`) in
interleaved rounds (the order reversed every other round), and checks that every image
is the one without skipping. Writes the `brick-size` block of docs/perf.md.

    python3 bench/brick_size.py [--vwb target/release/vwb] [--rounds 2] [--frames 3]

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
from raster_options import PRESETS, rgb

# (label, extra arguments, extra environment)
VARIANTS = [("skipping off", ["--skipping", "off"], {})] + [
    (f"bricks of {n}³" + (" (default)" if n == 8 else ""), [], {"VWB_SKIP_BRICK": str(n)})
    for n in (4, 8, 16, 32)
]


def main():
    ap = bench_parser(__doc__, "brick-size", 3, 2, "CT and nuclei, shaded and not")
    a = ap.parse_args()
    presets = a.preset or PRESETS
    tmp = Path(tempfile.gettempdir())
    times = {(p, v[0]): [] for p in presets for v in VARIANTS}
    adapter = "?"
    for r in range(a.rounds):
        order = list(enumerate(VARIANTS))
        if r % 2:
            order.reverse()
        for p in presets:
            for i, (label, extra, env_extra) in order:
                res = perf.run(a.vwb, p, "compute", a.size, a.frames, dict(vwb_env(a.gpu), **env_extra), extra)
                adapter = res["adapter"]
                times[(p, label)].append((res["gpu"] or res["wall"])[0])
                (tmp / f"vwb-bs-{Path(p).stem}-{i}.png").write_bytes((tmp / "vwb-perf.png").read_bytes())
    rows = ["| preset | variant | ms | ratio to 8³ | largest difference from the image without skipping |",
            "|---|---|---:|---:|---:|"]
    for p in presets:
        base = statistics.median(times[(p, VARIANTS[2][0])])
        ref = rgb(tmp / f"vwb-bs-{Path(p).stem}-0.png")
        for i, (label, *_rest) in enumerate(VARIANTS):
            m = statistics.median(times[(p, label)])
            d = rgb(tmp / f"vwb-bs-{Path(p).stem}-{i}.png") - ref
            rows.append(f"| `{Path(p).stem}` | {label} | {perf.ms(m)} | {m / base:.2f} | {int(np.abs(d).max())} |")
    publish(shlex.join(["python3", "bench/brick_size.py", *sys.argv[1:]]),
            f"{a.size}, compute backend, median over {a.rounds} interleaved rounds of each render's median "
            f"of {a.frames} frames after 2 warm-up frames (GPU ms).", adapter, a.gpu, rows, a.block,
            a.print_only)


if __name__ == "__main__":
    main()
