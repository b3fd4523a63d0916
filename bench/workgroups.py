#!/usr/bin/env python3
"""Workgroup shapes of the whole-frame compute passes (issue 23, item 4).

Renders each preset with every shape (`VWB_WORKGROUP=XxY`, the renderer option
`RendererOptions::workgroup`) in interleaved rounds, checks that every shape gives the
same image as 8×8 byte for byte, and writes the median frame times to the
`workgroups` block of docs/perf.md (on a GPU, `--gpu --block workgroups-gpu --doc
docs/gpu/perf.md`).

    python3 bench/workgroups.py [--vwb target/debug/vwb] [--rounds 2] [--frames 3]
"""

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import perf
from doclib import REPO, default_vwb, machine_line, round_order, vwb_env, write_block

SHAPES = ["8x8", "16x16", "16x4", "4x16", "32x2", "64x1", "4x4"]
PRESETS = ["presets/ct_shade_none.ron", "presets/ct_shade_phong.ron"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=default_vwb())
    ap.add_argument("--size", default="512x512")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--gpu", action="store_true")
    ap.add_argument("--block", default="workgroups")
    ap.add_argument("--doc", default=str(REPO / "docs/perf.md"))
    a = ap.parse_args()
    times = {(p, s): [] for p in PRESETS for s in SHAPES}
    adapter = "?"
    for r in range(a.rounds):
        order = round_order(SHAPES, r)
        for p in PRESETS:
            for s in order:
                env = dict(vwb_env(a.gpu), VWB_WORKGROUP=s)
                out = Path(tempfile.gettempdir()) / "vwb-perf.png"
                res = perf.run(a.vwb, p, "compute", a.size, a.frames, env)
                adapter = res["adapter"]
                times[(p, s)].append((res["gpu"] or res["wall"])[0])
                keep = Path(tempfile.gettempdir()) / f"vwb-wg-{Path(p).stem}-{s}.png"
                keep.write_bytes(out.read_bytes())
    same = {}
    for p in PRESETS:
        ref = (Path(tempfile.gettempdir()) / f"vwb-wg-{Path(p).stem}-8x8.png").read_bytes()
        same[p] = all((Path(tempfile.gettempdir()) / f"vwb-wg-{Path(p).stem}-{s}.png").read_bytes() == ref
                      for s in SHAPES)
    rows = ["| preset | " + " | ".join(s.replace("x", "×") for s in SHAPES) + " | same image |",
            "|---|" + "---:|" * len(SHAPES) + "---|"]
    for p in PRESETS:
        base = statistics.median(times[(p, "8x8")])
        cells = []
        for s in SHAPES:
            m = statistics.median(times[(p, s)])
            cells.append(f"{perf.ms(m)} ({m / base:.2f})")
        rows.append(f"| `{p}` | " + " | ".join(cells) + f" | {'yes' if same[p] else 'NO'} |")
    threads = os.environ.get("LP_NUM_THREADS")
    block = (
        f"Command: `python3 bench/workgroups.py{' --gpu' if a.gpu else ''}"
        f"{' --block ' + a.block if a.block != 'workgroups' else ''}"
        f"{' --doc ' + os.path.relpath(a.doc, REPO) if Path(a.doc).resolve() != (REPO / 'docs/perf.md').resolve() else ''}"
        f" --rounds {a.rounds} --frames {a.frames}` — "
        f"{a.size}, compute backend, median over {a.rounds} interleaved rounds of each render's "
        f"median of {a.frames} frames (GPU ms; in brackets the ratio to 8×8).\n\n"
        f"- Machine: {machine_line()}\n"
        f"- Adapter: {adapter}" + (f" (LP_NUM_THREADS={threads})" if threads and not a.gpu else "") + "\n\n"
        + "\n".join(rows) + "\n"
    )
    print(block)
    if not all(same.values()):
        sys.exit("a workgroup shape changed the image")
    write_block(Path(a.doc), a.block, block)


if __name__ == "__main__":
    main()
