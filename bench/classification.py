#!/usr/bin/env python3
"""Classification modes measured (the classification issue). The table (GPU time and
error against the converged post-classification reference for post / pre /
pre-integrated classification at slice spacings 0.5, 1, 2 and 4 voxels, on the demo
and the CT head) comes from the experiment file experiments/classification.ron, which
`vwb run` executes and which rewrites its own block in docs/classification.md. This
script runs it, then adds what an experiment file does not measure: the CPU time of a
pre-integration table rebuild (an ignored test), `vwb suggest-tf` timings and the
pre-integration gain per spacing. Rewrites the block between
<!-- BEGIN classification --> and <!-- END classification --> in docs/classification.md.

    python3 bench/classification.py            # lavapipe, LP_NUM_THREADS=2
    python3 bench/classification.py --gpu      # the best Vulkan adapter
"""

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from doclib import REPO, default_vwb, machine_line, vwb_env, write_block

# sample names (`vwb data list`), found in the data directory ($VWB_DATA_DIR)
SUGGEST = ["mri_head", "ct_head"]


def suggest_times(binary, env, tmp):
    """Wall time of `vwb suggest-tf` (process start, load and suggestion) per volume."""
    out = []
    for vol in SUGGEST:
        start = time.perf_counter()
        p = subprocess.run([binary, "suggest-tf", "--volume", vol, "-o", str(Path(tmp) / "tf.ron")],
                           cwd=REPO, env=env, capture_output=True, text=True)
        secs = time.perf_counter() - start
        if p.returncode != 0:
            sys.exit(f"vwb suggest-tf failed:\n{p.stderr}")
        out.append((vol, secs, p.stderr.strip().splitlines()[-1]))
    return out


def table_builds(env):
    """TABLE_BUILD lines of the ignored timing test."""
    p = subprocess.run(["bash", "bench/ignored_test.sh", "preintegration_table_build_time"],
                       cwd=REPO, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"the table-build timing test failed:\n{p.stdout}\n{p.stderr}")
    return [json.loads(l.split(" ", 1)[1]) for l in p.stdout.splitlines() if l.startswith("TABLE_BUILD ")]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=default_vwb())
    ap.add_argument("--gpu", action="store_true", help="use the best adapter instead of lavapipe")
    ap.add_argument("--doc", default=str(REPO / "docs/classification.md"))
    a = ap.parse_args()
    env = vwb_env(a.gpu)
    with tempfile.TemporaryDirectory() as tmp:
        p = subprocess.run([a.vwb, "run", "experiments/classification.ron", "-o", tmp],
                           cwd=REPO, env=env, capture_output=True, text=True)
        if p.returncode != 0:
            sys.exit(f"vwb run experiments/classification.ron failed:\n{p.stderr}")
        d = json.loads((Path(tmp) / "results.json").read_text())
        suggested = suggest_times(a.vwb, env, tmp)
    builds = table_builds(env)
    lines = [
        f"Machine: {machine_line()}; adapter: {d['adapter']}. "
        f"Command: `python3 bench/classification.py{' --gpu' if a.gpu else ''}`; the table is the "
        "experiment's block below (`vwb run experiments/classification.ron`).",
        "",
    ]
    for b in builds:
        lines.append(
            f"- Pre-integration table rebuild (256×256 from a 256-entry TF, CPU, one thread), `{b['preset']}`: "
            f"median {b['median']:.2f} ms (min {b['min']:.2f}, max {b['max']:.2f}) over {b['builds']} builds."
        )
    for vol, secs, msg in suggested:
        lines.append(f"- `vwb suggest-tf --volume {vol}`: {secs:.2f} s wall (load + histogram volume + suggestion); {msg.split(': ', 1)[-1].split('; wrote')[0]}")
    rows = d["rows"]
    lines += ["", "Pre-integration gain (post RMS ΔE*uv ÷ pre-integrated RMS ΔE*uv, same slices):", ""]
    for scene in sorted({r["scene"] for r in rows}):
        gains = []
        for sp in sorted({r["values"][0] for r in rows}):
            by = {r["variant"]: r for r in rows if r["scene"] == scene and r["values"][0] == sp}
            if "post" in by and "preintegrated" in by and by["preintegrated"]["metrics"]["rms_delta_e"] > 0:
                ratio = by["post"]["metrics"]["rms_delta_e"] / by["preintegrated"]["metrics"]["rms_delta_e"]
                gains.append(f"{sp:g} voxels: {ratio:.2f}×")
        lines.append(f"- `{scene}`: " + ", ".join(gains))
    block = "\n".join(lines)
    doc = Path(a.doc)
    write_block(doc, "classification" + ("-gpu" if a.gpu else ""), block)
    print(block)


if __name__ == "__main__":
    main()
