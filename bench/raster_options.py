#!/usr/bin/env python3
"""Early termination and skipping in the raster backend (issue 23, item 2).

Renders each preset with every variant in interleaved rounds (the order reversed every
other round) and writes the median frame times, their ratio to the plain raster
backend and each image's difference from the plain raster image (8-bit RGB RMS and
largest channel difference) to the `raster-options` block of docs/perf.md. Variants:

- raster: the shipped default, no early termination; its proxy polygons cover the
  visible box (the occupied bricks' bounding box) since session 46, the full box before,
  each drawn under a scissor to its part inside the occupied bricks' hull since session
  57 (the same image); "no hull" is the visible box alone (`VWB_HULL_PROXY=off`);
  since session 67 it skips the slices before each pixel's next visible brick by a
  depth mask every 16 slices (the same image): "no skipping" is the renderer without it
  (`VWB_RASTER_SKIP=0`), "skip every N" other run lengths (`VWB_RASTER_SKIP_INTERVAL`);
- the polygons cut to that hull (`--hull-cut on`), alone and with early termination;
- early termination 0.99 with a depth mask every N slices (`VWB_RASTER_ET_INTERVAL`);
- the occupied proxy: polygons cut to cells of C bricks per axis around the bricks
  that can be visible (`--occupied-proxy on`, `VWB_RASTER_PROXY_CELL`), fragments at
  their exact ray–plane point;
- both together, and the compute backend with and without early termination (the
  issue's target: raster within 1.3× of compute).

    python3 bench/raster_options.py [--vwb target/debug/vwb] [--rounds 2] [--frames 3]
    python3 bench/raster_options.py --gpu --block raster-options-gpu

Needs numpy and pillow (`pip install numpy pillow`; not part of the test set-up).
"""

import statistics
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

import perf
from doclib import bench_parser, publish, round_order, vwb_env

ET = ["--early-termination", "0.99"]
PROXY = ["--occupied-proxy", "on"]
CUT = ["--hull-cut", "on"]
# (label, backend, extra arguments, extra environment)
VARIANTS = [
    ("raster", "raster", [], {}),
    ("raster, no skipping", "raster", [], {"VWB_RASTER_SKIP": "0"}),
    ("raster, skip every 8", "raster", [], {"VWB_RASTER_SKIP_INTERVAL": "8"}),
    ("raster, skip every 32", "raster", [], {"VWB_RASTER_SKIP_INTERVAL": "32"}),
    ("raster, no hull", "raster", [], {"VWB_HULL_PROXY": "off"}),
    ("hull cut", "raster", CUT, {}),
    ("ET 0.99, mask every 8", "raster", ET, {"VWB_RASTER_ET_INTERVAL": "8"}),
    ("ET 0.99, mask every 16", "raster", ET, {"VWB_RASTER_ET_INTERVAL": "16"}),
    ("ET 0.99, mask every 32", "raster", ET, {"VWB_RASTER_ET_INTERVAL": "32"}),
    ("ET 0.99, mask every 64", "raster", ET, {"VWB_RASTER_ET_INTERVAL": "64"}),
    ("occupied proxy, cells of 2 bricks", "raster", PROXY, {"VWB_RASTER_PROXY_CELL": "2"}),
    ("occupied proxy, cells of 8 bricks", "raster", PROXY, {"VWB_RASTER_PROXY_CELL": "8"}),
    ("occupied proxy, one box", "raster", PROXY, {"VWB_RASTER_PROXY_CELL": "1000"}),
    ("occupied proxy (2) + ET 0.99 (32)", "raster", PROXY + ET,
     {"VWB_RASTER_PROXY_CELL": "2", "VWB_RASTER_ET_INTERVAL": "32"}),
    ("ET 0.99 (32), no skipping", "raster", ET,
     {"VWB_RASTER_ET_INTERVAL": "32", "VWB_RASTER_SKIP": "0"}),
    ("ET 0.99 (32), no hull", "raster", ET,
     {"VWB_RASTER_ET_INTERVAL": "32", "VWB_HULL_PROXY": "off"}),
    ("hull cut + ET 0.99 (32)", "raster", CUT + ET, {"VWB_RASTER_ET_INTERVAL": "32"}),
    ("compute", "compute", [], {}),
    ("compute, ET 0.99", "compute", ET, {}),
]
PRESETS = ["presets/demo.ron", "presets/ct_shade_none.ron", "presets/ct_shade_phong.ron",
           "presets/nuclei_shade_phong.ron"]


def rgb(path):
    return np.asarray(Image.open(path).convert("RGB")).astype(np.float64)


def main():
    ap = bench_parser(__doc__, "raster-options", 3, 3, "CT and nuclei, shaded and not")
    a = ap.parse_args()
    presets = a.preset or PRESETS
    tmp = Path(tempfile.gettempdir())
    times = {(p, v[0]): [] for p in presets for v in VARIANTS}
    adapter = "?"
    for r in range(a.rounds):
        order = round_order(VARIANTS, r)
        for p in presets:
            for label, backend, extra, env_extra in order:
                env = dict(vwb_env(a.gpu), **env_extra)
                res = perf.run(a.vwb, p, backend, a.size, a.frames, env, extra)
                adapter = res["adapter"]
                times[(p, label)].append((res["gpu"] or res["wall"])[0])
                keep = tmp / f"vwb-ro-{Path(p).stem}-{VARIANTS.index((label, backend, extra, env_extra))}.png"
                keep.write_bytes((tmp / "vwb-perf.png").read_bytes())
    rows = ["| preset | variant | ms | ratio to raster | RMS vs raster image (8-bit) | largest difference |",
            "|---|---|---:|---:|---:|---:|"]
    for p in presets:
        base = statistics.median(times[(p, "raster")])
        ref = rgb(tmp / f"vwb-ro-{Path(p).stem}-0.png")
        for i, (label, *_rest) in enumerate(VARIANTS):
            m = statistics.median(times[(p, label)])
            img = rgb(tmp / f"vwb-ro-{Path(p).stem}-{i}.png")
            d = img - ref
            rms = float(np.sqrt(np.mean(d ** 2)))
            rows.append(f"| `{Path(p).stem}` | {label} | {perf.ms(m)} | {m / base:.2f} | {rms:.2f} "
                        f"| {int(np.abs(d).max())} |")
    publish(f"python3 bench/raster_options.py{' --gpu --block ' + a.block if a.gpu else ''}",
            f"{a.size}, median over {a.rounds} interleaved rounds of each render's median of "
            f"{a.frames} frames (GPU ms).", adapter, a.gpu, rows, a.block, a.print_only)

if __name__ == "__main__":
    main()
