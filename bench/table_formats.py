#!/usr/bin/env python3
"""Classification tables in rgba16float against rgba32float on one adapter (issue 23:
the GPU's share of the raw sampling rate; docs/perf.md, "Classification tables in
16-bit floats on GPUs").

    python3 bench/table_formats.py --vwb target/release/vwb [--gpu] [-o OUT]

Runs `bench/ab.py` with `VWB_LUT_FORMAT=rgba32float` as A and `rgba16float` as B
(frame time and how far B's image is from A's) at 512² and 1024², and `vwb compare`
of both against the converged CPU reference and against the CPU twins at 256²
(RMS ΔE*uv), and writes OUT/ab_tables16_512.json, OUT/ab_tables16_1024.json and
OUT/accuracy_tables16.json (default OUT: docs/gpu/ with --gpu, else /tmp/vwb-tables).
The converged references take most of the time (150 s for 26 comparisons on 16 cores).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from doclib import REPO, default_vwb, vwb_env

AB_PRESETS = ["ct_head", "ct_shade_phong", "demo", "nuclei", "demo_tf2d", "demo_preintegrated",
              "demo_labels"]
ACCURACY_PRESETS = ["ct_head", "ct_shade_phong", "demo", "nuclei", "demo_tf2d",
                    "demo_preintegrated"]


def wrapper(folder: Path, vwb: str, fmt: str) -> str:
    p = folder / fmt
    p.write_text(f'#!/bin/sh\nVWB_LUT_FORMAT={fmt} exec "{vwb}" "$@"\n')
    p.chmod(0o755)
    return str(p)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=default_vwb())
    ap.add_argument("--gpu", action="store_true", help="use the best adapter instead of pinning lavapipe")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("-o", "--out")
    a = ap.parse_args()
    a.vwb = os.path.abspath(a.vwb)
    out = Path(a.out or (REPO / "docs/gpu" if a.gpu else "/tmp/vwb-tables"))
    out.mkdir(parents=True, exist_ok=True)
    env = vwb_env(a.gpu)
    with tempfile.TemporaryDirectory() as d:
        w32, w16 = (wrapper(Path(d), a.vwb, f) for f in ("rgba32float", "rgba16float"))
        presets = [arg for p in AB_PRESETS for arg in ("--preset", f"presets/{p}.ron")]
        for size, extra in [("512x512", ["--backend", "raster", "--images", "512x512"]), ("1024x1024", [])]:
            cmd = [sys.executable, str(REPO / "bench/ab.py"), "--a", w32, "--b", w16, *presets,
                   "--backend", "compute", *extra, "--rounds", str(a.rounds), "--frames", "20",
                   "--size", size, "-o", str(out / f"ab_tables16_{size.split('x')[0]}.json")]
            subprocess.run(cmd, cwd=REPO, env=env, check=True)
        rows, adapter = [], "?"
        for p in ACCURACY_PRESETS:
            for backend, against in [("compute", "converged"), ("raster", "converged"), ("compute", "reference")]:
                for fmt in ("rgba32float", "rgba16float"):
                    folder = Path(d) / f"{p}-{backend}-{against}-{fmt}"
                    r = subprocess.run([a.vwb, "compare", "--preset", f"presets/{p}.ron", "--size", "256x256",
                                        "--backend", backend, "--against", against, "-o", str(folder)],
                                       cwd=REPO, env=dict(env, VWB_LUT_FORMAT=fmt), capture_output=True, text=True)
                    if r.returncode != 0:
                        sys.exit(f"vwb compare {p} {backend} {against} {fmt} failed:\n{r.stderr}")
                    m = json.loads((folder / "metrics.json").read_text())
                    adapter = m["frame"]["adapter"]
                    row = dict(preset=p, backend=backend, against=against, tables=fmt,
                               **{k: m["metrics"][k] for k in ("rms_delta_e", "max_delta_e", "share_above_6")})
                    rows.append(row)
                    print(row, flush=True)
        (out / "accuracy_tables16.json").write_text(json.dumps(dict(
            adapter=adapter, size="256x256", command="python3 bench/table_formats.py" + (" --gpu" if a.gpu else ""),
            rows=rows), indent=1))


if __name__ == "__main__":
    main()
