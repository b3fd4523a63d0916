#!/usr/bin/env python3
"""Where the precomputed gradient estimators pay (issue 23, item 3): shade.blinn_phong's
`gradient` estimators timed against `central` at several image sizes (the default,
`auto`, takes `precomputed_central` on CPU adapters and `central` on GPUs since
session 64).

The issue asks to make the precomputed estimators the default "where they pay". Two
measurements disagreed: `bench/shading.py` (512²) found `precomputed_central` at 0.73×
`central`'s frame, the `cheap_shading` experiment (256²) found no gain. This script
renders `presets/ct_shade_phong.ron` and `presets/nuclei_shade_phong.ron` with each
estimator at 256², 512² and 1024² (compute backend, the presets' one slice per voxel)
in interleaved rounds, and writes each estimator's median frame time and its ratio to
`central`'s at the same size to the `estimators` block of docs/perf.md. The
estimators' errors against the converged reference are the `cheap_shading`
experiment's (`vwb run experiments/cheap_shading.ron`), not repeated here.

    python3 bench/estimators.py [--vwb target/debug/vwb] [--rounds 2] [--frames 3]
"""

import argparse
import re
import statistics
import tempfile
from pathlib import Path

import perf
from doclib import REPO, default_vwb, round_order, vwb_env, publish

PRESETS = ["presets/ct_shade_phong.ron", "presets/nuclei_shade_phong.ron"]
ESTIMATORS = ["central", "precomputed_central", "quantized"]
SIZES = [256, 512, 1024]


def variant(preset: str, estimator: str, tmp: Path) -> str:
    """`preset` with shade.blinn_phong's gradient estimator set to `estimator`."""
    text = (REPO / preset).read_text()
    text, n = re.subn(r'\(id: "shade.blinn_phong", params: \{\}\)',
                      f'(id: "shade.blinn_phong", params: {{"gradient": "{estimator}"}})', text)
    assert n == 1, f"{preset}: shade.blinn_phong with default parameters"
    path = tmp / f"{Path(preset).stem}_{estimator}.ron"
    path.write_text(text)
    return str(path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=default_vwb())
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--gpu", action="store_true")
    ap.add_argument("--block", default="estimators")
    ap.add_argument("--print-only", action="store_true")
    a = ap.parse_args()
    env = vwb_env(a.gpu)
    tmp = Path(tempfile.mkdtemp(prefix="vwb-estimators-"))
    files = {(p, e): variant(p, e, tmp) for p in PRESETS for e in ESTIMATORS}
    times = {(p, s, e): [] for p in PRESETS for s in SIZES for e in ESTIMATORS}
    adapter = "?"
    for r in range(a.rounds):
        for p in PRESETS:
            for s in SIZES:
                for e in round_order(ESTIMATORS, r):
                    res = perf.run(a.vwb, files[(p, e)], "compute", f"{s}x{s}", a.frames, env)
                    adapter = res["adapter"]
                    times[(p, s, e)].append((res["gpu"] or res["wall"])[0])
    rows = ["| preset | image | " + " | ".join(f"`{e}` ms (/ central)" for e in ESTIMATORS) + " |",
            "|---|---|" + "---:|" * len(ESTIMATORS)]
    for p in PRESETS:
        for s in SIZES:
            base = statistics.median(times[(p, s, "central")])
            cells = []
            for e in ESTIMATORS:
                m = statistics.median(times[(p, s, e)])
                cells.append(f"{m:.1f} ({m / base:.2f})")
            rows.append(f"| `{Path(p).stem}` | {s}² | " + " | ".join(cells) + " |")
    cmd = "python3 bench/estimators.py" + (" --gpu --block " + a.block if a.gpu else "")
    how = (f"compute backend, one slice per voxel, median over {a.rounds} interleaved rounds "
           f"of each render's median of {a.frames} frames after 2 warm-up frames (GPU ms; "
           "in brackets the ratio to `central` at the same size).")
    publish(cmd, how, adapter, a.gpu, rows, a.block, a.print_only)


if __name__ == "__main__":
    main()
