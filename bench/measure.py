#!/usr/bin/env python3
"""Speed–accuracy figures for docs/perf.md (the measurement issue).

Runs, with the vwb binary:
  1. `vwb compare --against converged` on the demo at 256²: how long the converged CPU
     reference takes and how it converged (target: < 10 s on 2 cores);
  2. `vwb sweep` over the slice spacing on the demo at 256², in rgba16float and
     rgba32float: time against RMS ΔE*uv to the converged reference, with the Pareto
     plots copied to docs/images/;
  3. `vwb bench` on the shipped demo presets: per-pass and per-plugin (ablation) GPU
     time and GPU memory per plugin.
It rewrites the block between <!-- BEGIN <block> --> and <!-- END <block> --> in
docs/perf.md. Rerun:

    python3 bench/measure.py                                # lavapipe, LP_NUM_THREADS=2
    python3 bench/measure.py --gpu --block measurement-gpu  # the best Vulkan adapter
"""

import argparse
import csv
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from doclib import REPO, default_vwb, machine_line, vwb_env, write_block

BENCH_PRESETS = ["presets/demo.ron", "presets/demo_slice_shadow.ron", "presets/demo_smooth.ron"]


def vwb(binary, args, env):
    p = subprocess.run([binary, *args], cwd=REPO, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"vwb {' '.join(args)} failed:\n{p.stderr}")
    return p


def converged(binary, env, size, tmp):
    out = tmp / "converged"
    vwb(binary, ["compare", "--preset", "presets/demo.ron", "--size", size,
                 "--against", "converged", "-o", str(out)], env)
    m = json.loads((out / "metrics.json").read_text())
    a = m["against"]
    steps = ", ".join(f"{s:g} → {d:.3f}" for s, d in a["steps"])
    return m["frame"]["adapter"], [
        f"**Converged reference** (`vwb compare --preset presets/demo.ron --size {size} --against converged`):",
        f"{a['seconds']:.2f} s on the CPU, converged = {a['converged']} at {a['spacing_voxels']:g} voxels "
        f"(spacing → RMS ΔE*uv change per halving: {steps}; tolerance {a['tolerance_rms_delta_e']}). "
        f"The GPU frame against it: RMS ΔE*uv {m['metrics']['rms_delta_e']:.3f}, "
        f"share > 6: {100 * m['metrics']['share_above_6']:.2f} %.",
    ]


def sweep(binary, env, size, target, tmp, images):
    out = tmp / f"sweep-{target}"
    spec = "render.slice_spacing=0.125..4:6:log"
    vwb(binary, ["sweep", "--preset", "presets/demo.ron", "--size", size, "--target", target,
                 "--param", spec, "-o", str(out)], env)
    plot = images / f"sweep_demo_{target}.svg"
    shutil.copyfile(out / "pareto.svg", plot)
    rows = list(csv.DictReader(open(out / "sweep.csv")))
    lines = [
        f"**Sweep, {target}** (`vwb sweep --preset presets/demo.ron --size {size} --target {target} "
        f"--param {spec}`), plot: [{plot.name}](images/{plot.name})",
        "",
        "| spacing (voxels) | slices | frame ms | RMS ΔE*uv | max ΔE*uv | > 6 | SSIM | Pareto |",
        "|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for r in rows:
        lines.append(
            f"| {float(r['render.slice_spacing']):g} | {r['slices']} | {float(r['frame_ms']):.1f} ({r['clock']}) | "
            f"{float(r['rms_delta_e']):.3f} | {float(r['max_delta_e']):.2f} | "
            f"{100 * float(r['share_above_6']):.2f} % | {float(r['ssim']):.4f} | "
            f"{'yes' if r['pareto'] == 'true' else ''} |"
        )
    return lines


def bench(binary, env, size, frames, tmp):
    lines = [
        f"**Per pass and per plugin** (`vwb bench --preset P --size {size} --frames {frames}`; "
        "`plugin` = frame time with the instance minus without it, medians; "
        "`cold prepass` = the pre-pass in the first frame, it reruns only when its inputs change):",
        "",
        "| preset | row | clock | median ms (min–max) | GPU memory |",
        "|---|---|---|---|---:|",
    ]
    for preset in BENCH_PRESETS:
        out = tmp / (Path(preset).stem + ".csv")
        vwb(binary, ["bench", "--preset", preset, "--size", size, "--frames", str(frames),
                     "-o", str(out)], env)
        for r in csv.DictReader(open(out)):
            if r["kind"] == "memory":
                mem = f"{int(r['bytes']) / 1024:.1f} KiB"
                lines.append(f"| {Path(preset).stem} | memory {r['name']} | | | {mem} |")
                continue
            spread = "" if r["kind"] in ("plugin", "cold_pass") else f" ({float(r['min_ms']):.1f}–{float(r['max_ms']):.1f})"
            name = r["name"] if r["kind"] != "frame" else "frame"
            kind = {"cold_pass": "cold", "pass": "pass", "plugin": "plugin", "frame": ""}[r["kind"]]
            lines.append(f"| {Path(preset).stem} | {(kind + ' ' + name).strip()} | {r['clock']} | "
                         f"{float(r['median_ms']):.2f}{spread} | |")
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=default_vwb())
    ap.add_argument("--size", default="256x256")
    ap.add_argument("--bench-size", default="512x512")
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--gpu", action="store_true", help="use the best adapter instead of pinning lavapipe")
    ap.add_argument("--block", default="measurement")
    ap.add_argument("--doc", default=str(REPO / "docs/perf.md"))
    ap.add_argument("--print-only", action="store_true")
    a = ap.parse_args()
    env = vwb_env(a.gpu)
    images = REPO / "docs/images"
    images.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        adapter, conv = converged(a.vwb, env, a.size, tmp)
        sweeps = [sweep(a.vwb, env, a.size, t, tmp, images) for t in ("rgba16float", "rgba32float")]
        benches = bench(a.vwb, env, a.bench_size, a.frames, tmp)
    cmd = "python3 bench/measure.py" + (f" --gpu --block {a.block}" if a.gpu else "")
    lines = [
        f"Command: `{cmd}` (release build).",
        "",
        f"- Machine: {machine_line()}",
        f"- Adapter: {adapter}" + ("" if a.gpu else f" (LP_NUM_THREADS={env['LP_NUM_THREADS']})"),
        "",
        *conv,
        "",
    ]
    for s in sweeps:
        lines += [*s, ""]
    lines += benches
    block = "\n".join(lines)
    if not a.print_only:
        write_block(Path(a.doc), a.block, block)
    print(block)


if __name__ == "__main__":
    main()
