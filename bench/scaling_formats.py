#!/usr/bin/env python3
"""Does the volume's storage format change how the time per sample scales? (issue 23,
the time-per-sample target.)

The `scaling` block (bench/scaling.py) finds the CT head's sample dearer where pixels
and samples lie further apart than voxels (256², spacing 2). This renders the CT head
as `bench/scaling.py` does (compute backend, empty-space skipping off) in each
volume format (`--volume-format`: r32float_pairs, what CPU devices store by default;
r32float, half its bytes; r16unorm, a quarter) at the sizes and spacings where the
ratio moves, in --rounds interleaved rounds, the least of each configuration's
medians, and writes the `scaling-formats` block of docs/perf.md: per format the time
per sample and its ratio to the same format's sample at 512², spacing 1.

    python3 bench/scaling_formats.py [--vwb target/release/vwb] [--rounds 3] [--frames 3]
"""

import argparse

from doclib import REPO, default_vwb, machine_line, vwb_env, write_block
from scaling import least_of_rounds, num, render

FORMATS = ["r32float_pairs", "r32float", "r16unorm"]
CONFIGS = [(256, 2.0), (256, 1.0), (512, 2.0), (512, 1.0), (1024, 1.0)]
PRESET = REPO / "presets/ct_head.ron"


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=default_vwb())
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--print-only", action="store_true")
    a = ap.parse_args()
    env = vwb_env(False)
    configs = [(f, n, sp) for f in FORMATS for n, sp in CONFIGS]
    res = least_of_rounds(configs, a.rounds, lambda c: render(
        a.vwb, PRESET, c[1], c[2], "off", a.frames, env, ["--volume-format", c[0]]))
    adapter = next(iter(res.values()))["adapter"]
    ns = {c: r["ms"] * 1e6 / (c[1] * c[1] * r["slices"]) for c, r in res.items()}
    head = "| format | " + " | ".join(f"{n}², spacing {sp:g}" for n, sp in CONFIGS) + " |"
    rows = [head, "|---|" + "---:|" * len(CONFIGS)]
    for f in FORMATS:
        base = ns[(f, 512, 1.0)]
        rows.append(f"| {f} | " + " | ".join(
            f"{num(ns[(f, n, sp)], 2)} ns ({ns[(f, n, sp)] / base:.2f})" for n, sp in CONFIGS) + " |")
    lines = [
        f"Command: `python3 bench/scaling_formats.py --rounds {a.rounds} --frames {a.frames}` — "
        "the CT head, `vwb render --timings --volume-format F`, compute backend, skipping off, "
        f"the least over {a.rounds} interleaved rounds of each configuration's median of "
        f"{a.frames} frames (GPU ms).",
        "",
        f"- Machine: {machine_line()}",
        f"- Adapter: {adapter} (LP_NUM_THREADS={env['LP_NUM_THREADS']})",
        "",
        "Time per sample (ns per pixel and slice; in brackets the ratio to the same "
        "format's sample at 512², spacing 1):",
        "",
        *rows,
        "",
    ]
    text = "\n".join(lines)
    print(text)
    if not a.print_only:
        write_block(REPO / "docs/perf.md", "scaling-formats", text)


if __name__ == "__main__":
    main()
