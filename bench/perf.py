#!/usr/bin/env python3
"""Frame-time table for docs/perf.md (foundation benchmarks).

Runs `vwb render --timings` for the demo and the CT head at 512², one slice per
voxel, raster and compute (and the compute march's samples with nothing but a
trilinear fetch each, `VWB_RAW_SAMPLES=1`, for the share of the raw sampling rate that
plain DVR reaches), and rewrites the block between
<!-- BEGIN <block> --> and <!-- END <block> --> in docs/perf.md with a table, the
machine and the adapter. Rerun:

    python3 bench/perf.py                         # CPU Vulkan (lavapipe), LP_NUM_THREADS=2
    python3 bench/perf.py --gpu --block foundation-gpu   # the best Vulkan adapter
"""

import argparse
import re
import subprocess
import sys
import tempfile
from pathlib import Path

from doclib import REPO, default_vwb, machine_line, vwb_env, write_block

CASES = [
    ("demo (MRI 128×128×84)", "presets/demo.ron"),
    ("CT head 256×256×108", "presets/ct_head.ron"),
]


# `VWB_RAW_SAMPLES=1`: the compute march's samples with one trilinear fetch each and
# nothing else (`Renderer::set_raw_samples`), the rate plain DVR is measured against.
RAW = "compute, raw samples: one trilinear fetch each, nothing else"


def run(vwb, preset, backend, size, frames, env, extra=()):
    out = Path(tempfile.gettempdir()) / "vwb-perf.png"
    cmd = [vwb, "render", "--preset", preset, "--size", size, "--backend", backend,
           "--timings", "--frames", str(frames), "-o", str(out), *extra]
    p = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{p.stderr}")
    text = p.stdout + p.stderr
    def grab(key):
        m = re.search(rf"{key} median ([\d.]+) min ([\d.]+) max ([\d.]+)", text)
        return tuple(float(x) for x in m.groups()) if m else None
    slices = re.search(r"(\d+) slices", text)
    adapter = re.search(r"adapter: (.*)", text)
    return {
        "wall": grab("wall_ms"),
        "gpu": grab("gpu_ms"),
        "slices": int(slices.group(1)) if slices else 0,
        "adapter": adapter.group(1).strip() if adapter else "?",
    }


def ms(x: float) -> str:
    """One decimal, two below 10 ms (GPU frames take fractions of one)."""
    return f"{x:.1f}" if x >= 10 else f"{x:.2f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=default_vwb())
    ap.add_argument("--size", default="512x512")
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--gpu", action="store_true", help="use the best adapter instead of pinning lavapipe")
    ap.add_argument("--block", default="foundation")
    ap.add_argument("--doc", default=str(REPO / "docs/perf.md"))
    ap.add_argument("--print-only", action="store_true")
    ap.add_argument("--ct-preset", default="presets/ct_head.ron",
                    help="CT head preset (e.g. a copy whose volume path suits another machine)")
    a = ap.parse_args()
    env = vwb_env(a.gpu)
    rows = []
    shares = []
    adapter = "?"
    cases = [(n, a.ct_preset if "CT" in n else p) for n, p in CASES]
    raw_env = {**env, "VWB_RAW_SAMPLES": "1"}
    for name, preset in cases:
        plain = raw = None
        for backend, extra in (
            ("raster", ()),
            ("compute", ()),
            ("compute, no empty-space skipping", ("--skipping", "off")),
            ("compute, early termination 0.99", ("--early-termination", "0.99")),
            (RAW, ("--skipping", "off")),
        ):
            r = run(a.vwb, preset, backend.split(",")[0], a.size, a.frames,
                    raw_env if backend == RAW else env, extra)
            adapter = r["adapter"]
            g = r["gpu"]
            w = r["wall"]
            t = (g or w)[0]
            if backend == RAW:
                raw = t
            elif "no empty-space" in backend:
                plain = t
            rows.append(
                f"| {name} | {backend} | {r['slices']} | "
                + (f"{ms(g[0])} ({ms(g[1])}–{ms(g[2])})" if g else "n/a")
                + f" | {ms(w[0])} |"
            )
        shares.append(f"{name}: {100 * raw / plain:.0f} % ({ms(raw)} ms of raw sampling "
                      f"against {ms(plain)} ms of DVR)")
    build = "release" if "/release/" in a.vwb else "debug (the GPU's time does not depend on it)"
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO,
                            capture_output=True, text=True).stdout.strip() or "?"
    cmd = "python3 bench/perf.py" + (" --gpu --block " + a.block if a.gpu else "")
    if a.size != "512x512":
        cmd += f" --size {a.size}"
    doc = Path(a.doc).resolve()
    if doc != (REPO / "docs/perf.md").resolve():
        cmd += f" --doc {doc.relative_to(REPO.resolve()) if doc.is_relative_to(REPO.resolve()) else doc}"
    lines = [
        f"Command: `{cmd}` ({build} build of vwb, {commit}; `vwb render --timings`, median of {a.frames} frames after 2 warm-up frames).",
        "",
        f"- Machine: {machine_line()}",
        f"- Adapter: {adapter}" + ("" if a.gpu else f" (LP_NUM_THREADS={env['LP_NUM_THREADS']})"),
        f"- Image {a.size}, one slice per voxel (slice spacing 1), rgba16float eye buffer, classify.tf1d, empty-space skipping on (it acts in the compute backend) and early termination off unless the backend column says otherwise",
        "",
        "| volume | backend | slices | GPU ms median (min–max) | wall ms median |",
        "|---|---|---|---|---|",
        *rows,
        "",
        "Share of the raw trilinear sampling rate that plain DVR reaches (the raw-samples "
        "frame's time over the compute frame's without skipping, the same samples): "
        + "; ".join(shares) + ".",
    ]
    block = "\n".join(lines)
    if a.print_only:
        print(block)
        return
    write_block(Path(a.doc), a.block, block)
    print(block)


if __name__ == "__main__":
    main()
