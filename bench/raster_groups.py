#!/usr/bin/env python3
"""Several slices per proxy polygon on the raster backend (Rezk-Salama 2001, §9.1;
issue 23, item 2): `render.slices_per_proxy`, `vwb render --slices-per-proxy N`.

Renders each preset on the raster backend with 1, 2, 4, 8 and 16 slices per polygon
and on the compute backend, without early termination and with it (0.99 on both), in
interleaved rounds (the order reversed every other round), and writes to the
`raster-groups` block of docs/perf.md, per preset and variant:

- the median frame time (GPU ms) and its ratio to the raster backend's polygon per
  slice and to the compute backend (the issue's target: raster within 1.3× of
  compute), each against the variant with the same early termination;
- the image's difference from the polygon-per-slice image (8-bit RGB RMS, largest);
- the RMS ΔE*uv of a `--twin-size` image against the CPU twins (`vwb compare`, the
  f64 reference renderer with the fp16 target emulated), for every variant.

    python3 bench/raster_groups.py [--vwb target/debug/vwb] [--rounds 3] [--frames 3]
        [--groups 1,2,4,8,16,auto] [--twin-size 128x128 | 0] [--block raster-groups]
        [--targets preset,rgba32float]

`--targets` repeats every variant at each eye-buffer precision it names (`preset`: the
preset's own, `rgba16float`, `rgba32float`; `vwb render --target`), in the same
interleaved rounds; each variant's ratios are to the polygon per slice and to compute
at its own precision.

Needs numpy and pillow (`pip install numpy pillow`; not part of the test set-up).
"""

import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

import perf
from doclib import REPO, bench_parser, publish, round_order, vwb_env

ET = ["--early-termination", "0.99"]


def variants(groups, targets=("preset",)):
    """(label, backend, extra arguments, key) of each variant: the groups and compute,
    without and with early termination, at each eye-buffer precision of `targets`
    (`preset`: the preset's own); `key` (precision, termination) names the variants a
    ratio compares within."""
    out = []
    for t in targets:
        suffix, tx = ("", []) if t == "preset" else (f", {t}", ["--target", t])
        for et, ex, es in (False, [], ""), (True, ET, ", ET 0.99"):
            out += [(f"raster, {n} per polygon{' (the default)' if n == 'auto' else ''}"
                     f"{suffix}{es}", "raster",
                     ["--slices-per-proxy", str(n)] + tx + ex, (t, et)) for n in groups]
            out += [(f"compute{suffix}{es}", "compute", tx + ex, (t, et))]
    return out
PRESETS = ["presets/demo.ron", "presets/ct_shade_none.ron", "presets/ct_shade_phong.ron",
           "presets/nuclei.ron"]


def rgb(path):
    return np.asarray(Image.open(path).convert("RGB")).astype(np.float64)


def twin_error(vwb, preset, backend, extra, size, env):
    out = Path(tempfile.mkdtemp(prefix="vwb-rg-"))
    cmd = [vwb, "compare", "--preset", preset, "--size", size, "--backend", backend,
           "--frames", "1", "-o", str(out), *extra]
    p = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{p.stderr}")
    return json.loads((out / "metrics.json").read_text())["metrics"]["rms_delta_e"]


def main():
    ap = bench_parser(__doc__, "raster-groups", 3, 3, "demo, CT head unshaded and Blinn–Phong, nuclei")
    ap.add_argument("--twin-size", default="128x128", help="0: no twin column")
    ap.add_argument("--groups", default="1,2,4,8,16",
                    help="slices per polygon (1 first; auto: the default, 8 with "
                         "termination and 1 without)")
    ap.add_argument("--targets", default="preset",
                    help="eye-buffer precisions, comma-separated: preset (the preset's), "
                         "rgba16float, rgba32float")
    a = ap.parse_args()
    groups = [n if n == "auto" else int(n) for n in a.groups.split(",")]
    if groups[0] != 1:
        sys.exit("--groups starts with 1 (the ratios are to a polygon per slice)")
    targets = a.targets.split(",")
    if not set(targets) <= {"preset", "rgba16float", "rgba32float"}:
        sys.exit(f"--targets {a.targets}: preset, rgba16float or rgba32float")
    VARIANTS = variants(groups, targets)
    presets = a.preset or PRESETS
    env = vwb_env(a.gpu)
    tmp = Path(tempfile.gettempdir())
    times = {(p, v[0]): [] for p in presets for v in VARIANTS}
    adapter = "?"
    for r in range(a.rounds):
        for p in presets:
            for label, backend, extra, _ in round_order(VARIANTS, r):
                res = perf.run(a.vwb, p, backend, a.size, a.frames, env, extra)
                adapter = res["adapter"]
                times[(p, label)].append((res["gpu"] or res["wall"])[0])
                keep = tmp / f"vwb-rg-{Path(p).stem}-{[v[0] for v in VARIANTS].index(label)}.png"
                keep.write_bytes((tmp / "vwb-perf.png").read_bytes())
    twins = a.twin_size != "0"
    rows = ["| preset | variant | ms | ratio to a polygon per slice | ratio to compute | "
            "RMS vs a polygon per slice (8-bit) | largest difference |"
            + (" twins ΔE*uv RMS |" if twins else ""),
            "|---|---|---:|---:|---:|---:|---:|" + ("---:|" if twins else "")]
    labels = [v[0] for v in VARIANTS]
    for p in presets:
        stem = Path(p).stem
        for i, (label, backend, extra, key) in enumerate(VARIANTS):
            # the polygon per slice and compute at this variant's precision and termination
            one = next(j for j, v in enumerate(VARIANTS) if v[3] == key and v[1] == "raster")
            comp = next(j for j, v in enumerate(VARIANTS) if v[3] == key and v[1] == "compute")
            m = statistics.median(times[(p, label)])
            base = statistics.median(times[(p, labels[one])])
            c = statistics.median(times[(p, labels[comp])])
            d = rgb(tmp / f"vwb-rg-{stem}-{i}.png") - rgb(tmp / f"vwb-rg-{stem}-{one}.png")
            rms = float(np.sqrt(np.mean(d ** 2)))
            row = (f"| `{stem}` | {label} | {perf.ms(m)} | {m / base:.2f} | {m / c:.2f} "
                   f"| {rms:.2f} | {int(np.abs(d).max())} |")
            if twins:
                row += f" {twin_error(a.vwb, p, backend, extra, a.twin_size, env):.3f} |"
            rows.append(row)
    # the command as run, less the binary and --print-only
    shown, skip = [], False
    for arg in sys.argv[1:]:
        if skip or arg == "--print-only":
            skip = False
            continue
        if arg == "--vwb":
            skip = True
            continue
        if not arg.startswith("--vwb="):
            shown.append(arg)
    args = " ".join(shown)
    publish(f"python3 bench/raster_groups.py{' ' + args if args else ''}",
            f"{a.size}, median over {a.rounds} interleaved rounds of each render's median of "
            f"{a.frames} frames (GPU ms)" + (f"; twins at {a.twin_size}." if twins else "."),
            adapter, a.gpu, rows, a.block, a.print_only)


if __name__ == "__main__":
    main()
