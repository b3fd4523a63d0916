#!/usr/bin/env python3
"""Shading benchmarks for docs/perf.md (issue: local illumination).

1. Frame time per shading model at 512² on the switchboard presets
   (presets/{ct,nuclei}_shade_{none,phong,envmap,iso}.ron, which differ only in the
   shading plugin), compute and raster, from `vwb render --timings`.
2. Gradient estimators of shade.blinn_phong on the CT head (compute): frame time, the
   plugin's marginal cost (ablation), the pre-pass time and the GPU memory, from
   `vwb bench`. Lavapipe's timestamps do not bracket the pre-pass, so its time is
   taken from wall clocks: (first frame − warm frame) of the precomputed estimator
   minus the same difference for `central` (which has no pre-pass).

Rerun (rewrites the `shading` block of docs/perf.md):

    python3 bench/shading.py                  # CPU Vulkan (lavapipe), LP_NUM_THREADS=2
    python3 bench/shading.py --gpu --block shading-gpu
"""

import argparse
import csv
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import perf
from doclib import REPO, default_vwb, machine_line, vwb_env, write_block

MODELS = [("none", "none"), ("phong", "Blinn–Phong"), ("envmap", "environment map"),
          ("iso", "isosurface (+DVR)")]
VOLUMES = [("ct", "CT head 256×256×108"), ("nuclei", "nuclei 256×256×60")]
ESTIMATORS = ["central", "sobel", "precomputed_central", "precomputed_sobel", "quantized"]


def run(cmd, env):
    p = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(map(str, cmd))} failed:\n{p.stderr}")
    return p.stdout + p.stderr


def render_ms(vwb, preset, backend, size, frames, env):
    """(median, min, max) GPU ms (wall without timestamps) and the adapter."""
    r = perf.run(vwb, preset, backend, size, frames, env)
    return r["gpu"] or r["wall"], r["adapter"]


def estimator_preset(estimator):
    """ct_shade_phong.ron with the estimator set and the volume path made absolute."""
    src = (REPO / "presets/ct_shade_phong.ron").read_text()
    src = src.replace('(id: "shade.blinn_phong", params: {})',
                      f'(id: "shade.blinn_phong", params: {{"gradient": "{estimator}"}})')
    src = re.sub(r'File\("([^"]+)"\)',
                 lambda m: f'File("{(REPO / "presets" / m.group(1)).resolve()}")', src)
    p = Path(tempfile.gettempdir()) / f"vwb-shading-{estimator}.ron"
    p.write_text(src)
    return p


def bench(vwb, preset, size, frames, env):
    out = Path(tempfile.gettempdir()) / "vwb-shading-bench.csv"
    run([vwb, "bench", "--preset", str(preset), "--size", size, "--frames", str(frames),
         "-o", str(out)], env)
    rows = list(csv.DictReader(out.open()))
    get = lambda kind, name, clock: next(
        (r for r in rows if r["kind"] == kind and r["name"].startswith(name) and r["clock"] == clock), None)
    frame = get("frame", "frame", "gpu") or get("frame", "frame", "wall")
    return {
        "frame": float(frame["median_ms"]),
        "warm_wall": float(get("frame", "frame", "wall")["median_ms"]),
        "cold_wall": float(get("cold_frame", "frame", "wall")["median_ms"]),
        "plugin": float(get("plugin", "shade.blinn_phong", frame["clock"])["median_ms"]),
        "bytes": int(get("memory", "shade.blinn_phong", "")["bytes"]),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=default_vwb())
    ap.add_argument("--size", default="512x512")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--gpu", action="store_true", help="the best Vulkan adapter, not lavapipe")
    ap.add_argument("--block", default="shading")
    ap.add_argument("--doc", type=Path, default=REPO / "docs/perf.md")
    ap.add_argument("--no-write", action="store_true")
    a = ap.parse_args()
    env = vwb_env(a.gpu)

    lines = ["| volume | shading | compute ms | raster ms | compute / none |", "|---|---|---|---|---|"]
    adapter = "?"
    for vol, vol_label in VOLUMES:
        base = None
        for key, label in MODELS:
            preset = f"presets/{vol}_shade_{key}.ron"
            c, adapter = render_ms(a.vwb, preset, "compute", a.size, a.frames, env)
            r, _ = render_ms(a.vwb, preset, "raster", a.size, a.frames, env)
            base = base or c[0]
            lines.append(f"| {vol_label} | {label} | {c[0]:.0f} ({c[1]:.0f}–{c[2]:.0f}) "
                         f"| {r[0]:.0f} ({r[1]:.0f}–{r[2]:.0f}) | {c[0] / base:.2f} |")
            print(lines[-1], flush=True)

    est = ["", "| gradient estimator (Blinn–Phong, CT, compute) | frame ms | shading plugin ms (ablation) "
           "| pre-pass ms (wall) | plugin GPU memory |", "|---|---|---|---|---|"]
    results = {e: bench(a.vwb, estimator_preset(e), a.size, a.frames, env) for e in ESTIMATORS}
    overhead = results["central"]["cold_wall"] - results["central"]["warm_wall"]
    for e in ESTIMATORS:
        r = results[e]
        pre = (r["cold_wall"] - r["warm_wall"] - overhead) if e.startswith("precomputed") else None
        est.append(f"| {e} | {r['frame']:.0f} | {r['plugin']:.0f} | "
                   f"{'—' if pre is None else f'{pre:.0f}'} | {r['bytes'] / 2**20:.1f} MiB |")
        print(est[-1], flush=True)

    lp = "" if a.gpu else " (LP_NUM_THREADS=2)"
    block = "\n".join([
        f"Command: `python3 bench/shading.py{' --gpu' if a.gpu else ''}` — median (min–max) of "
        f"{a.frames} frames at {a.size}, one slice per voxel, empty-space skipping on (the "
        "isosurface plugin turns it off: it makes opacity where the classification has none).",
        "",
        f"- Machine: {machine_line()}",
        f"- Adapter: {adapter}{lp}",
        "",
        *lines,
        *est,
        "",
        "The pre-pass volume is rgba16float (∇f·Δs0 and |∇f|), 8 bytes per voxel: "
        "256×256×108 → 54 MiB.",
    ])
    print()
    print(block)
    if not a.no_write:
        write_block(a.doc, a.block, block)
        print(f"rewrote <!-- BEGIN {a.block} --> in {a.doc}")


if __name__ == "__main__":
    main()
