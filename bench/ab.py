#!/usr/bin/env python3
"""Frame time of two vwb builds in one interleaved run (A B A B ...), for a change that
must not regress speed.

    python3 bench/ab.py --a OLD/vwb --b NEW/vwb [--preset presets/demo.ron ...]
        [--rounds 4] [--frames 5] [--size 512x512] [-o docs/ab.json]

Each round runs `vwb bench` of every preset with A, then with B (B first in odd
rounds); the figure per build is the median over rounds of the frame's GPU median
(wall time where the adapter has no timestamps). Prints a Markdown table, with the
median of the rounds' own B / A ratios beside the ratio of the medians.

    python3 bench/ab.py ... --clock cpu [--bench-arg=--early-termination --bench-arg=0.99]

compares the process's CPU time per frame instead (all threads, user + system: on a
CPU adapter the frame's work itself, which a shared host's steal does not inflate as it
does the clocks; not a frame time), and passes further options on to `vwb bench`.

    python3 bench/ab.py --a OLD/vwb --b NEW/vwb --gallery presets/demo_tf2d.ron ...
        [--rounds 4] [--pool 512] [--tile 16]

times design galleries instead (`vwb gallery --preset P --pool N --k 4 --tile T`, the
time it reports for its thumbnails: set-up, renders and read-back), and checks that
both builds choose the same genomes with the same dispersion.

    python3 bench/ab.py ... --images 256x256

also renders every preset and backend once with each build (`vwb render`, that size)
and adds how far B's 8-bit image is from A's: RMS and largest difference in levels, and
the pixels that differ (needs numpy and pillow). The JSON names the machine and the
adapter.

Build OLD in a target folder of its own, e.g.

    git worktree add /tmp/old REV && (cd /tmp/old && CARGO_TARGET_DIR=/tmp/old-target cargo build)

Not in the repository's target/: Cargo leaves the source folder out of a workspace
member's artefact hash, so the old build takes the same slots, and the repository's
next `cargo build` can find them fresh and keep the old code (it did in session 52).
"""
import argparse
import csv
import json
import os
import re
import statistics
import subprocess
import tempfile

from doclib import machine_line, round_order


def frame_ms(binary, preset, frames, size, backend, clock="frame", extra=()):
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "b.csv")
        cmd = [binary, "bench", "--preset", preset, "--frames", str(frames),
               "--warmup", "2", "--size", size, "-o", out]
        if backend:
            cmd += ["--backend", backend]
        cmd += list(extra)
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        with open(out) as f:
            for row in csv.DictReader(f):
                if row["kind"] == "frame" and (clock == "frame" or row["clock"] == clock):
                    return float(row["median_ms"]), row["clock"]
    raise RuntimeError(f"{binary}: no frame row for {preset}")


def adapter_of(binary, preset):
    """The adapter line `vwb render` prints."""
    with tempfile.TemporaryDirectory() as d:
        p = subprocess.run([binary, "render", "--preset", preset, "--size", "16x16",
                            "-o", os.path.join(d, "a.png")], capture_output=True, text=True)
    m = re.search(r"adapter: (.*)", p.stdout + p.stderr)
    return m.group(1).strip() if m else "?"


def image_diff(a, b, preset, backend, size):
    """(RMS, max, differing pixels) of B's 8-bit RGB render against A's."""
    import numpy as np
    from PIL import Image
    with tempfile.TemporaryDirectory() as d:
        imgs = []
        for name, binary in (("a", a), ("b", b)):
            out = os.path.join(d, f"{name}.png")
            subprocess.run([binary, "render", "--preset", preset, "--size", size, "--backend", backend,
                            "-o", out], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            imgs.append(np.asarray(Image.open(out).convert("RGB")).astype(float))
    diff = np.abs(imgs[0] - imgs[1])
    return float(np.sqrt((diff ** 2).mean())), float(diff.max()), int((diff.max(axis=2) > 0).sum())


def gallery_ms(binary, preset, pool, tile):
    """The thumbnails' time `vwb gallery` reports, and its summary line after the time."""
    with tempfile.TemporaryDirectory() as d:
        p = subprocess.run([binary, "gallery", "--preset", preset, "--pool", str(pool), "--k", "4",
                            "--tile", str(tile), "-o", d], check=True, capture_output=True, text=True)
    m = re.search(r"thumbnails in (\d+) ms \([^)]*\); (.*)", p.stderr)
    if not m:
        raise RuntimeError(f"{binary}: no timing in\n{p.stderr}")
    return float(m.group(1)), m.group(2)


def galleries(a):
    times, summaries = {}, {}
    for r in range(a.rounds):
        order = round_order([("a", a.a), ("b", a.b)], r)
        for p in a.gallery:
            for name, binary in order:
                ms, summary = gallery_ms(binary, p, a.pool, a.tile)
                times.setdefault((p, name), []).append(ms)
                summaries.setdefault(p, set()).add(summary)
    print(f"| preset | pool × 3 views, {a.tile}² | A ms | B ms | B / A | same picks |")
    print("|---|---:|---:|---:|---:|---|")
    for p in a.gallery:
        ta = statistics.median(times[(p, "a")])
        tb = statistics.median(times[(p, "b")])
        same = "yes" if len(summaries[p]) == 1 else "NO"
        print(f"| {p} | {a.pool} | {ta:.0f} | {tb:.0f} | {tb / ta:.3f} | {same} |")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--a", required=True)
    ap.add_argument("--b", required=True)
    ap.add_argument("--preset", action="append")
    ap.add_argument("--backend", action="append")
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--size", default="512x512")
    ap.add_argument("-o")
    ap.add_argument("--gallery", action="append", help="time design galleries of this preset instead")
    ap.add_argument("--pool", type=int, default=512)
    ap.add_argument("--tile", type=int, default=16)
    ap.add_argument("--images", metavar="WxH", help="also compare the builds' images at this size")
    ap.add_argument("--clock", choices=["frame", "cpu"], default="frame",
                    help="frame: the frame's GPU median (wall without timestamps); cpu: the process's "
                         "CPU time per frame, all threads (steadier on a shared CPU host, not a frame time)")
    ap.add_argument("--bench-arg", action="append", default=[], metavar="ARG",
                    help="passed on to `vwb bench` (repeat per word, e.g. --bench-arg=--early-termination "
                         "--bench-arg=0.99)")
    a = ap.parse_args()
    if a.gallery:
        galleries(a)
        return
    presets = a.preset or ["presets/demo.ron", "presets/ct_head.ron"]
    backends = a.backend or ["compute", "raster"]
    times = {}
    for r in range(a.rounds):
        order = round_order([("a", a.a), ("b", a.b)], r)
        for p in presets:
            for be in backends:
                for name, binary in order:
                    ms, clock = frame_ms(binary, p, a.frames, a.size, be, a.clock, a.bench_arg)
                    times.setdefault((p, be, name), []).append(ms)
    rows = []
    images = f" | image B vs A at {a.images}: RMS, max (levels), pixels differing" if a.images else ""
    unit = "CPU ms" if a.clock == "cpu" else "ms"
    print(f"| preset | backend | A {unit} | B {unit} | B / A | B / A per round (median){images} |")
    print("|---|---|---:|---:|---:|---:" + ("|---:" if a.images else "") + "|")
    for p in presets:
        for be in backends:
            ta = statistics.median(times[(p, be, "a")])
            tb = statistics.median(times[(p, be, "b")])
            per_round = statistics.median(y / x for x, y in zip(times[(p, be, "a")], times[(p, be, "b")]))
            row = {"preset": p, "backend": be, "a_ms": ta, "b_ms": tb, "ratio": tb / ta,
                   "ratio_of_rounds": per_round,
                   "a_rounds": times[(p, be, "a")], "b_rounds": times[(p, be, "b")]}
            cell = ""
            if a.images:
                rms, mx, n = image_diff(a.a, a.b, p, be, a.images)
                row.update({"image_size": a.images, "image_rms_levels": rms, "image_max_levels": mx,
                            "image_pixels_differing": n})
                cell = f" | {rms:.3f}, {mx:.0f}, {n}"
            rows.append(row)
            print(f"| {p} | {be} | {ta:.1f} | {tb:.1f} | {tb / ta:.3f} | {per_round:.3f}{cell} |")
    if a.o:
        with open(a.o, "w") as f:
            json.dump({"a": a.a, "b": a.b, "size": a.size, "frames": a.frames, "clock": a.clock,
                       "bench_args": a.bench_arg,
                       "rounds": a.rounds, "machine": machine_line(),
                       "adapter": adapter_of(a.b, presets[0]),
                       "lp_num_threads": os.environ.get("LP_NUM_THREADS"), "rows": rows}, f, indent=2)


if __name__ == "__main__":
    main()
