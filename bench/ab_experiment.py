#!/usr/bin/env python3
"""An experiment file run by two vwb builds in interleaved rounds (A B, B A, ...): the
median of each variant's update (or another time column, `--metric apply_ms`) and
frame time per build, their ratio, whether the error columns agree, and whether the two
builds' images are the same bytes (the first round's), for a change that must keep
the images and change the time.

    python3 bench/ab_experiment.py --a OLD/vwb --b NEW/vwb \\
        --experiment experiments/flow_integrators.ron [--rounds 3] [--metric update_ms] [-o docs/ab_x.json]

Each run writes its report to a temporary folder (`vwb run FILE -o DIR`), so the doc
block the experiment names is not rewritten. Prints a Markdown table.
"""
import argparse
import csv
import json
import os
import statistics
import subprocess
import tempfile

from doclib import machine_line, round_order


def run(binary, experiment):
    """The rows of one run's results.csv, each with its image's bytes."""
    with tempfile.TemporaryDirectory() as d:
        subprocess.run([binary, "run", experiment, "-o", d], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        with open(os.path.join(d, "results.csv")) as f:
            rows = list(csv.DictReader(f))
        for row in rows:
            path = os.path.join(d, row["image"]) if row.get("image") else None
            row["image_bytes"] = open(path, "rb").read() if path and os.path.isfile(path) else None
        return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--a", required=True)
    ap.add_argument("--b", required=True)
    ap.add_argument("--experiment", required=True)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--metric", default="update_ms", help="the time column compared (default update_ms)")
    ap.add_argument("-o")
    a = ap.parse_args()
    runs = {"a": [], "b": []}
    for r in range(a.rounds):
        order = round_order([("a", a.a), ("b", a.b)], r)
        for name, binary in order:
            runs[name].append(run(binary, a.experiment))
    key = lambda row: (row["scene"], row["variant"])
    m = a.metric
    rows = []
    print(f"| scene | variant | A {m} | B {m} | B / A | A frame ms | B frame ms | RMS ΔE*uv A → B | images |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---|")
    for first in runs["a"][0]:
        k = key(first)
        if any(r["variant"] == k[1] and r["scene"] == k[0] for r in rows):
            continue
        pick = lambda name, col: [float(row[col]) for run_rows in runs[name] for row in run_rows if key(row) == k]
        ua, ub = statistics.median(pick("a", m)), statistics.median(pick("b", m))
        fa, fb = statistics.median(pick("a", "frame_ms")), statistics.median(pick("b", "frame_ms"))
        ea, eb = pick("a", "rms_delta_e")[0], pick("b", "rms_delta_e")[0]
        images = [row["image_bytes"] for name in ("a", "b") for row in runs[name][0] if key(row) == k]
        half = len(images) // 2
        same = images[:half] == images[half:]
        ratio = ub / ua if ua > 0 else float("nan")
        rows.append({"scene": k[0], "variant": k[1], "metric": m, "a": ua, "b": ub,
                     "ratio": ratio, "a_frame_ms": fa, "b_frame_ms": fb,
                     "a_rms_delta_e": ea, "b_rms_delta_e": eb, "images_identical": same})
        err = "—" if ea != ea else f"{ea:.3f} → {eb:.3f}"
        print(f"| {k[0]} | {k[1]} | {ua:.2f} | {ub:.2f} | {ratio:.2f} | {fa:.1f} | {fb:.1f} | {err} | "
              f"{'identical' if same else 'DIFFER'} |")
    if a.o:
        with open(a.o, "w") as f:
            json.dump({"a": a.a, "b": a.b, "experiment": a.experiment, "rounds": a.rounds,
                       "machine": machine_line(), "lp_num_threads": os.environ.get("LP_NUM_THREADS"),
                       "rows": rows}, f, indent=2)


if __name__ == "__main__":
    main()
