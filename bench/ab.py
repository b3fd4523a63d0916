#!/usr/bin/env python3
"""Frame time of two vwb builds in one interleaved run (A B A B ...), for a change that
must not regress speed.

    python3 bench/ab.py --a OLD/vwb --b NEW/vwb [--preset presets/demo.ron ...]
        [--rounds 4] [--frames 5] [--size 512x512] [-o docs/ab.json]

Each round runs `vwb bench` of every preset with A, then with B (B first in odd
rounds); the figure per build is the median over rounds of the frame's GPU median
(wall time where the adapter has no timestamps). Prints a Markdown table.
"""
import argparse
import csv
import json
import os
import statistics
import subprocess
import tempfile


def frame_ms(binary, preset, frames, size, backend):
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "b.csv")
        cmd = [binary, "bench", "--preset", preset, "--frames", str(frames),
               "--warmup", "2", "--size", size, "-o", out]
        if backend:
            cmd += ["--backend", backend]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        with open(out) as f:
            for row in csv.DictReader(f):
                if row["kind"] == "frame":
                    return float(row["median_ms"]), row["clock"]
    raise RuntimeError(f"{binary}: no frame row for {preset}")


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
    a = ap.parse_args()
    presets = a.preset or ["presets/demo.ron", "presets/ct_head.ron"]
    backends = a.backend or ["compute", "raster"]
    times = {}
    for r in range(a.rounds):
        order = [("a", a.a), ("b", a.b)] if r % 2 == 0 else [("b", a.b), ("a", a.a)]
        for p in presets:
            for be in backends:
                for name, binary in order:
                    ms, clock = frame_ms(binary, p, a.frames, a.size, be)
                    times.setdefault((p, be, name), []).append(ms)
    rows = []
    print("| preset | backend | A ms | B ms | B / A |")
    print("|---|---|---:|---:|---:|")
    for p in presets:
        for be in backends:
            ta = statistics.median(times[(p, be, "a")])
            tb = statistics.median(times[(p, be, "b")])
            rows.append({"preset": p, "backend": be, "a_ms": ta, "b_ms": tb, "ratio": tb / ta,
                         "a_rounds": times[(p, be, "a")], "b_rounds": times[(p, be, "b")]})
            print(f"| {p} | {be} | {ta:.1f} | {tb:.1f} | {tb / ta:.3f} |")
    if a.o:
        with open(a.o, "w") as f:
            json.dump({"a": a.a, "b": a.b, "size": a.size, "frames": a.frames,
                       "rounds": a.rounds, "rows": rows}, f, indent=2)


if __name__ == "__main__":
    main()
