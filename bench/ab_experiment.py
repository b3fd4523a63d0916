#!/usr/bin/env python3
"""An experiment file run by two vwb builds in interleaved rounds (A B, B A, ...): the
median of each variant's update and frame time per build, their ratio, and whether
the error columns agree, for a change that must keep the images and change the time.

    python3 bench/ab_experiment.py --a OLD/vwb --b NEW/vwb \\
        --experiment experiments/flow_integrators.ron [--rounds 3] [-o docs/ab_x.json]

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
    """The rows of one run's results.csv."""
    with tempfile.TemporaryDirectory() as d:
        subprocess.run([binary, "run", experiment, "-o", d], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        with open(os.path.join(d, "results.csv")) as f:
            return list(csv.DictReader(f))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--a", required=True)
    ap.add_argument("--b", required=True)
    ap.add_argument("--experiment", required=True)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("-o")
    a = ap.parse_args()
    runs = {"a": [], "b": []}
    for r in range(a.rounds):
        order = round_order([("a", a.a), ("b", a.b)], r)
        for name, binary in order:
            runs[name].append(run(binary, a.experiment))
    key = lambda row: (row["scene"], row["variant"])
    rows = []
    print("| scene | variant | A update ms | B update ms | B / A | A frame ms | B frame ms | RMS ΔE*uv A → B |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for first in runs["a"][0]:
        k = key(first)
        pick = lambda name, col: [float(row[col]) for run_rows in runs[name] for row in run_rows if key(row) == k]
        ua, ub = statistics.median(pick("a", "update_ms")), statistics.median(pick("b", "update_ms"))
        fa, fb = statistics.median(pick("a", "frame_ms")), statistics.median(pick("b", "frame_ms"))
        ea, eb = pick("a", "rms_delta_e")[0], pick("b", "rms_delta_e")[0]
        ratio = ub / ua if ua > 0 else float("nan")
        rows.append({"scene": k[0], "variant": k[1], "a_update_ms": ua, "b_update_ms": ub,
                     "update_ratio": ratio, "a_frame_ms": fa, "b_frame_ms": fb,
                     "a_rms_delta_e": ea, "b_rms_delta_e": eb})
        err = "—" if ea != ea else f"{ea:.3f} → {eb:.3f}"
        print(f"| {k[0]} | {k[1]} | {ua:.1f} | {ub:.1f} | {ratio:.2f} | {fa:.1f} | {fb:.1f} | {err} |")
    if a.o:
        with open(a.o, "w") as f:
            json.dump({"a": a.a, "b": a.b, "experiment": a.experiment, "rounds": a.rounds,
                       "machine": machine_line(), "lp_num_threads": os.environ.get("LP_NUM_THREADS"),
                       "rows": rows}, f, indent=2)


if __name__ == "__main__":
    main()
