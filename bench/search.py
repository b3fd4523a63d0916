#!/usr/bin/env python3
"""Design galleries measured: thumbnail throughput of the batched atlas at 64² and 128²
and the dispersion of the 36 chosen against 36 drawn at random, on the CT head, the
nuclei and the demo with a 2D TF (classify.tf2d: 2D genomes), each from `vwb gallery` (gallery.json). Rewrites the block between
<!-- BEGIN search --> and <!-- END search --> in docs/search.md and copies the CT
gallery image to docs/images/gallery_ct.png.

    python3 bench/search.py            # lavapipe, LP_NUM_THREADS=2
    python3 bench/search.py --gpu      # the best adapter: docs/gpu/search.md, and
                                       # 1024 × 3 thumbnails at 128² as well
"""

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from doclib import REPO, default_vwb, machine_line, vwb_env, write_block

RUNS = [
    ("presets/ct_head.ron", 1024, 64),
    ("presets/ct_head.ron", 256, 128),
    ("presets/nuclei.ron", 1024, 64),
    ("presets/demo_tf2d.ron", 1024, 64),
]


GPU_RUNS = RUNS + [("presets/ct_head.ron", 1024, 128)]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--gpu", action="store_true", help="use the best adapter; write docs/gpu/search.md")
    ap.add_argument("--vwb", default=None, help="the vwb binary (default: the most recently built)")
    a = ap.parse_args()
    vwb = a.vwb or default_vwb()
    env = vwb_env(a.gpu)
    rows = []
    adapter = ""
    with tempfile.TemporaryDirectory() as tmp:
        for i, (preset, pool, tile) in enumerate(GPU_RUNS if a.gpu else RUNS):
            out = Path(tmp) / f"g{i}"
            p = subprocess.run([vwb, "gallery", "--preset", preset, "--pool", str(pool), "--k", "36",
                                "--tile", str(tile), "--seed", "1", "-o", str(out)],
                               cwd=REPO, env=env, capture_output=True, text=True)
            if p.returncode != 0:
                sys.exit(f"vwb gallery failed:\n{p.stderr}")
            g = json.loads((out / "gallery.json").read_text())
            adapter = g["adapter"]
            rows.append(
                f"| `{preset}` | {pool} × {g['views']} | {tile}² | {g['thumbnails_per_s']:.1f} | "
                f"{g['dispersion_min_delta_e']:.2f} | {g['random_dispersion_min_delta_e']:.2f} | "
                f"{g['dispersion_min_delta_e'] / max(g['random_dispersion_min_delta_e'], 1e-9):.1f}× |")
            if i == 0 and not a.gpu:
                (REPO / "docs" / "images").mkdir(exist_ok=True)
                shutil.copy(out / "gallery.png", REPO / "docs" / "images" / "gallery_ct.png")
    block = "\n".join([
        f"Machine: {machine_line()}; adapter: {adapter}. Command: `python3 bench/search.py"
        f"{' --gpu' if a.gpu else ''}` "
        "(`vwb gallery --preset P --pool N --k 36 --tile T --seed 1`).",
        "",
        "| scene | pool × views | tile | thumbnails/s (atlas) | min pairwise ΔE*uv, 36 chosen | the same, first 36 drawn | ratio |",
        "|---|---:|---:|---:|---:|---:|---:|",
        *rows,
    ])
    write_block(REPO / "docs" / ("gpu/search.md" if a.gpu else "search.md"), "search", block)
    print(block)


if __name__ == "__main__":
    main()
