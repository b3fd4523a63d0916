#!/usr/bin/env python3
"""Classification modes measured (the classification issue): GPU time and error
against the converged post-classification reference for post / pre / pre-integrated
classification at slice spacings 0.5, 1, 2 and 4 voxels, on the demo and the CT head,
plus the CPU time of a pre-integration table rebuild. Rewrites the block between
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

SCENES = ["presets/demo_preintegrated.ron", "presets/ct_skin.ron"]
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


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=default_vwb())
    ap.add_argument("--gpu", action="store_true", help="use the best adapter instead of lavapipe")
    ap.add_argument("--size", default="256x256")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--doc", default=str(REPO / "docs/classification.md"))
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        args = [a.vwb, "classification", "--size", a.size, "--frames", str(a.frames), "-o", tmp]
        for s in SCENES:
            args += ["--scene", s]
        p = subprocess.run(args, cwd=REPO, env=vwb_env(a.gpu), capture_output=True, text=True)
        if p.returncode != 0:
            sys.exit(f"vwb classification failed:\n{p.stderr}")
        d = json.loads((Path(tmp) / "classification.json").read_text())
        suggested = suggest_times(a.vwb, vwb_env(a.gpu), tmp)

    lines = [
        f"Machine: {machine_line()}; adapter: {d['adapter']}. Image {a.size}, eye buffer "
        f"{d['target']}, time = {d['time']} of {d['frames']} frames. "
        f"Command: `python3 bench/classification.py{' --gpu' if a.gpu else ''}`.",
        "",
    ]
    for ref in d["references"]:
        lines.append(
            f"- Reference for `{ref['preset']}`: converged post-classification at "
            f"{ref['spacing_voxels']:g} voxels, last halving changed RMS ΔE*uv by "
            f"{ref['last_change_rms_delta_e']:.3f} (converged: {ref['converged']}), {ref['seconds']:.1f} s on the CPU."
        )
    for b in d["table_builds"]:
        t = b["table_build_ms"]
        lines.append(
            f"- Pre-integration table rebuild (256×256 from a 256-entry TF, CPU, one thread), `{b['preset']}`: "
            f"median {t['median']:.2f} ms (min {t['min']:.2f}, max {t['max']:.2f}) over 50 builds."
        )
    for vol, secs, msg in suggested:
        lines.append(f"- `vwb suggest-tf --volume {vol}`: {secs:.2f} s wall (load + histogram volume + suggestion); {msg.split(': ', 1)[-1].split('; wrote')[0]}")
    lines += ["", "| scene | spacing (voxels) | slices | mode | time (ms) | RMS ΔE*uv | ΔE > 6 |",
              "|---|---:|---:|---|---:|---:|---:|"]
    rows = sorted(d["rows"], key=lambda r: (r["preset"], r["spacing"], ["post", "pre", "preintegrated"].index(r["mode"])))
    for r in rows:
        lines.append(
            f"| {r['preset']} | {r['spacing']:g} | {r['slices']} | {r['mode']} | {r['gpu_ms']:.2f} | "
            f"{r['rms_delta_e']:.2f} | {100 * r['share_above_6']:.1f} % |"
        )
    lines += ["", "Pre-integration gain (post RMS ΔE*uv ÷ pre-integrated RMS ΔE*uv, same slices):", ""]
    for scene in sorted({r["preset"] for r in rows}):
        gains = []
        for sp in sorted({r["spacing"] for r in rows}):
            by = {r["mode"]: r for r in rows if r["preset"] == scene and r["spacing"] == sp}
            if "post" in by and "preintegrated" in by and by["preintegrated"]["rms_delta_e"] > 0:
                gains.append(f"{sp:g} voxels: {by['post']['rms_delta_e'] / by['preintegrated']['rms_delta_e']:.2f}×")
        lines.append(f"- `{scene}`: " + ", ".join(gains))
    block = "\n".join(lines)
    doc = Path(a.doc)
    if not doc.exists():
        doc.write_text("# Classification\n")
    write_block(doc, "classification" + ("-gpu" if a.gpu else ""), block)
    print(block)


if __name__ == "__main__":
    main()
