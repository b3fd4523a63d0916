#!/usr/bin/env python3
"""Frame-time table for docs/perf.md (foundation benchmarks).

Runs `vwb render --timings` for the demo and the CT head at 512², one slice per
voxel, raster and compute, and rewrites the block between
<!-- BEGIN <block> --> and <!-- END <block> --> in docs/perf.md with a table, the
machine and the adapter. Rerun:

    python3 bench/perf.py                         # CPU Vulkan (lavapipe), LP_NUM_THREADS=2
    python3 bench/perf.py --gpu --block foundation-gpu   # the best Vulkan adapter
"""

import argparse
import os
import platform
import re
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
CASES = [
    ("demo (MRI 128×128×84)", "presets/demo.ron"),
    ("CT head 256×256×108", "presets/ct_head.ron"),
]


def cpu_model() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def run(vwb, preset, backend, size, frames, env):
    out = Path(tempfile.gettempdir()) / "vwb-perf.png"
    cmd = [vwb, "render", "--preset", preset, "--size", size, "--backend", backend,
           "--timings", "--frames", str(frames), "-o", str(out)]
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


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=str(REPO / "target/release/vwb"))
    ap.add_argument("--size", default="512x512")
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--gpu", action="store_true", help="use the best adapter instead of pinning lavapipe")
    ap.add_argument("--block", default="foundation")
    ap.add_argument("--doc", default=str(REPO / "docs/perf.md"))
    ap.add_argument("--print-only", action="store_true")
    ap.add_argument("--ct-preset", default="presets/ct_head.ron",
                    help="CT head preset (e.g. a copy whose volume path suits another machine)")
    a = ap.parse_args()
    env = dict(os.environ)
    env.setdefault("XDG_RUNTIME_DIR", "/tmp")
    if not a.gpu:
        env["VK_DRIVER_FILES"] = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json"
        env.setdefault("LP_NUM_THREADS", "2")
    rows = []
    adapter = "?"
    cases = [(n, a.ct_preset if "CT" in n else p) for n, p in CASES]
    for name, preset in cases:
        for backend in ("raster", "compute"):
            r = run(a.vwb, preset, backend, a.size, a.frames, env)
            adapter = r["adapter"]
            g = r["gpu"]
            w = r["wall"]
            rows.append(
                f"| {name} | {backend} | {r['slices']} | "
                + (f"{g[0]:.1f} ({g[1]:.1f}–{g[2]:.1f})" if g else "n/a")
                + f" | {w[0]:.1f} |"
            )
    cmd = "python3 bench/perf.py" + (" --gpu --block " + a.block if a.gpu else "")
    lines = [
        f"Command: `{cmd}` (release build; `vwb render --timings`, median of {a.frames} frames after 2 warm-up frames).",
        "",
        f"- Machine: {cpu_model()}, {os.cpu_count()} cores, {platform.system()} {platform.release()}",
        f"- Adapter: {adapter}" + ("" if a.gpu else f" (LP_NUM_THREADS={env['LP_NUM_THREADS']})"),
        f"- Image {a.size}, one slice per voxel (slice spacing 1), rgba16float eye buffer, classify.tf1d, no early termination",
        "",
        "| volume | backend | slices | GPU ms median (min–max) | wall ms median |",
        "|---|---|---|---|---|",
        *rows,
    ]
    block = "\n".join(lines)
    if a.print_only:
        print(block)
        return
    doc = Path(a.doc)
    text = doc.read_text() if doc.exists() else "# Performance\n"
    begin, end = f"<!-- BEGIN {a.block} -->", f"<!-- END {a.block} -->"
    if begin in text and end in text:
        pre, rest = text.split(begin, 1)
        _, post = rest.split(end, 1)
        text = f"{pre}{begin}\n{block}\n{end}{post}"
    else:
        text = text.rstrip() + f"\n\n{begin}\n{block}\n{end}\n"
    doc.write_text(text)
    print(block)


if __name__ == "__main__":
    main()
