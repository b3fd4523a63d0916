#!/usr/bin/env python3
"""How frame time scales (issue 23, targets): with pixels × samples, and with empty space.

1. Linearity: the demo and the CT head, compute backend, empty-space skipping off (every
   sample inside the volume's box is taken), at 256², 512² and 1024² and slice spacings
   0.5, 1 and 2 voxels. The time per sample is the frame's GPU time over
   width × height × slices; the issue's target is that it stays within ±20 % of the
   median over the table.
   Where the time per sample goes: the same presets and sizes at the coarser spacings
   4, 8 and 64 as well; the frame at spacing 64 (a handful of slices) is about the cost
   per pixel, and the difference between neighbouring spacings over the samples they
   add is the marginal cost of a sample at that spacing.
2. Empty space: the CT head at 512², spacing 1, compute, with a 1D TF ramp that starts
   at a threshold t (0 below it, opacity rising to 0.8 at 1): the higher t, the more
   bricks are empty. Each threshold with skipping on and off: the share of empty
   bricks, both times and their ratio.

Each configuration: `vwb render --timings` (median of --frames frames after 2 warm-up
frames), run in --rounds interleaved rounds (the order reversed in odd rounds); the
table gives the least of the rounds' medians. Rewrites the block between
<!-- BEGIN scaling --> and <!-- END scaling --> in docs/perf.md.

    python3 bench/scaling.py                 # lavapipe, LP_NUM_THREADS=2
    python3 bench/scaling.py --gpu --doc docs/gpu/perf.md
"""

import argparse
import math
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from doclib import REPO, default_vwb, machine_line, round_order, vwb_env, write_block

PRESETS = [("demo", "presets/demo.ron"), ("CT head", "presets/ct_head.ron")]
SIZES = [256, 512, 1024]
SPACINGS = [0.5, 1.0, 2.0]
# the decomposition's further spacings (not part of the target's table)
COARSE = [4.0, 8.0, 64.0]
THRESHOLDS = [0.05, 0.2, 0.3, 0.4, 0.6]


def num(x: float, decimals: int, sig: int = 3) -> str:
    """`x` with at least `decimals` decimals and at least `sig` significant digits (a
    GPU's frames take fractions of a millisecond, its samples thousandths of a ns)."""
    if x == 0 or not math.isfinite(x):
        return f"{x:.{decimals}f}"
    return f"{x:.{max(decimals, sig - 1 - math.floor(math.log10(abs(x))))}f}"


def render(vwb, preset, size, spacing, skipping, frames, env, extra=()):
    out = Path(tempfile.gettempdir()) / "vwb-scaling.png"
    cmd = [vwb, "render", "--preset", str(preset), "--size", f"{size}x{size}",
           "--backend", "compute", "--spacing", str(spacing), "--skipping", skipping,
           "--timings", "--frames", str(frames), "-o", str(out), *extra]
    p = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{p.stderr}")
    text = p.stdout + p.stderr
    gpu = re.search(r"gpu_ms median ([\d.]+)", text)
    slices = re.search(r"(\d+) slices", text)
    empty = re.search(r"empty_bricks ([\d.]+|off)", text)
    adapter = re.search(r"adapter: (.*)", text)
    return {
        "ms": float(gpu.group(1)),
        "slices": int(slices.group(1)),
        "empty": None if not empty or empty.group(1) == "off" else float(empty.group(1)),
        "adapter": adapter.group(1).strip() if adapter else "?",
    }


def ramp_preset(threshold: float, tmp: Path) -> Path:
    """The CT head preset with its TF replaced by a ramp from `threshold`."""
    text = (REPO / "presets/ct_head.ron").read_text()
    tf = (f'"tf": (points: [(x: 0.0, color: (1.0, 1.0, 1.0, 0.0)), '
          f'(x: {threshold}, color: (1.0, 1.0, 1.0, 0.0)), (x: 1.0, color: (1.0, 1.0, 1.0, 0.8))]),')
    text, n = re.subn(r'"tf": \(points: \[.*?\]\),', tf, text, flags=re.S)
    assert n == 1, "the CT head preset's TF"
    path = tmp / f"ct_ramp_{threshold}.ron"
    path.write_text(text)
    return path


def least_of_rounds(configs, rounds, run):
    """Each config's result with the least ms over `rounds` interleaved rounds."""
    best = {}
    for r in range(rounds):
        for c in round_order(configs, r):
            res = run(c)
            if c not in best or res["ms"] < best[c]["ms"]:
                best[c] = res
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=default_vwb())
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--gpu", action="store_true", help="the best adapter instead of lavapipe")
    ap.add_argument("--doc", default=str(REPO / "docs/perf.md"))
    ap.add_argument("--print-only", action="store_true")
    a = ap.parse_args()
    env = vwb_env(a.gpu)
    tmp = Path(tempfile.mkdtemp(prefix="vwb-scaling-"))

    lin = [(name, preset, size, spacing) for name, preset in PRESETS for size in SIZES for spacing in SPACINGS]
    coarse = [(name, preset, size, spacing) for name, preset in PRESETS for size in SIZES for spacing in COARSE]
    res = least_of_rounds(lin + coarse, a.rounds,
                          lambda c: render(a.vwb, REPO / c[1], c[2], c[3], "off", a.frames, env))
    adapter = next(iter(res.values()))["adapter"]
    rows, verdicts = [], []
    for name, _ in PRESETS:
        mine = [(c, res[c]) for c in lin if c[0] == name]
        ns = {c: r["ms"] * 1e6 / (c[2] * c[2] * r["slices"]) for c, r in mine}
        med = statistics.median(ns.values())
        for c, r in mine:
            rows.append(f"| {name} | {c[2]}² | {c[3]} | {r['slices']} | {num(r['ms'], 1)} | "
                        f"{num(ns[c], 3)} | {ns[c] / med:.2f} |")
        lo, hi = min(ns.values()) / med, max(ns.values()) / med
        met = "met" if lo >= 0.8 and hi <= 1.2 else "not met"
        verdicts.append(f"{name}: {lo:.2f}–{hi:.2f} of the median {num(med, 3)} ns ({met})")

    # where the time per sample goes: per pixel, and the marginal cost per sample
    rows3 = []
    spacings = SPACINGS + COARSE
    for name, preset in PRESETS:
        for size in SIZES:
            rs = [res[(name, preset, size, sp)] for sp in spacings]
            px = size * size
            marg = [(f["ms"] - c["ms"]) * 1e6 / (px * (f["slices"] - c["slices"]))
                    for f, c in zip(rs, rs[1:])]
            rows3.append(f"| {name} | {size}² | {num(rs[-1]['ms'] * 1e6 / px, 0)} ({rs[-1]['slices']} slices) | "
                         + " | ".join(num(m, 2) for m in marg) + " |")
    pairs = " | ".join(f"{f:g} → {c:g}" for f, c in zip(spacings, spacings[1:]))

    thr = [(t, s) for t in THRESHOLDS for s in ("on", "off")]
    presets = {t: ramp_preset(t, tmp) for t in THRESHOLDS}
    res2 = least_of_rounds(thr, a.rounds,
                           lambda c: render(a.vwb, presets[c[0]], 512, 1.0, c[1], a.frames, env))
    rows2 = []
    for t in THRESHOLDS:
        on, off = res2[(t, "on")], res2[(t, "off")]
        rows2.append(f"| {t} | {on['empty'] * 100:.1f} % | {num(on['ms'], 1)} | {num(off['ms'], 1)} | "
                     f"{on['ms'] / off['ms']:.2f} |")

    cmd = "python3 bench/scaling.py" + (" --gpu --doc " + a.doc if a.gpu else "")
    lines = [
        f"Command: `{cmd}` — `vwb render --timings`, compute backend, the least over {a.rounds} "
        f"interleaved rounds of each configuration's median of {a.frames} frames after 2 warm-up "
        "frames (GPU ms).",
        "",
        f"- Machine: {machine_line()}",
        f"- Adapter: {adapter}" + ("" if a.gpu else f" (LP_NUM_THREADS={env['LP_NUM_THREADS']})"),
        "",
        "Time per sample, empty-space skipping off (ns per pixel and slice; ratio to the "
        "preset's median):",
        "",
        "| volume | image | spacing (voxels) | slices | ms | ns per sample | / median |",
        "|---|---|---:|---:|---:|---:|---:|",
        *rows,
        "",
        "Spread of the time per sample (target: within ±20 % of the median): "
        + "; ".join(verdicts) + ".",
        "",
        "Where the time per sample goes: the frame at spacing 64 per pixel (ns), and the "
        "marginal cost of a sample between neighbouring spacings (ns: the difference of "
        "the two frames over pixels × the slices the finer one adds):",
        "",
        f"| volume | image | per pixel at spacing 64 | {pairs} |",
        "|---|---|---:|" + "---:|" * (len(spacings) - 1),
        *rows3,
        "",
        "Empty space: the CT head at 512², spacing 1, a TF ramp from the threshold "
        "(0 below it, opacity up to 0.8 at 1):",
        "",
        "| threshold | empty bricks | skipping on (ms) | skipping off (ms) | on / off |",
        "|---:|---:|---:|---:|---:|",
        *rows2,
    ]
    block = "\n".join(lines)
    if a.print_only:
        print(block)
        return
    write_block(Path(a.doc), "scaling", block)
    print(block)


if __name__ == "__main__":
    main()
