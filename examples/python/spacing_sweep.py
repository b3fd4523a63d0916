#!/usr/bin/env python3
"""A slice-spacing sweep from Python: time and error against the converged reference
for post- and pre-integrated classification of the demo, plotted with matplotlib.

    pip install .            # from the repository root (the `vwb` package)
    python3 examples/python/spacing_sweep.py [--out sweep.png]
"""

import argparse
from pathlib import Path

import vwb

REPO = Path(__file__).resolve().parents[2]


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--preset", default=str(REPO / "presets" / "demo_preintegrated.ron"))
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--out", default="spacing_sweep.png")
    a = ap.parse_args()
    size = (a.size, a.size)
    spacings = [0.25, 0.5, 1.0, 2.0, 4.0]
    s = vwb.Scene(a.preset)
    s.set("classify.tf1d.mode", "post")
    reference = s.converged(size=size)
    print(f"adapter: {vwb.adapter()}")
    print(f"{'mode':>14} {'spacing':>8} {'slices':>7} {'ms':>9} {'RMS ΔE*uv':>10}")
    series = {}
    for mode in ["post", "preintegrated"]:
        s.set("classify.tf1d.mode", mode)
        for spacing in spacings:
            t = s.time(size=size, spacing=spacing, frames=3)
            e = vwb.compare(s.render(size=size, spacing=spacing), reference)["rms_delta_e"]
            series.setdefault(mode, []).append((t["frame_ms"], e, spacing))
            print(f"{mode:>14} {spacing:>8} {t['slices']:>7} {t['frame_ms']:>9.2f} {e:>10.3f}")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no plot")
        return
    fig, ax = plt.subplots(figsize=(6, 4))
    for mode, pts in series.items():
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=mode)
        for ms, e, sp in pts:
            ax.annotate(f"{sp}", (ms, e), textcoords="offset points", xytext=(4, 4), fontsize=8)
    ax.set_xlabel(f"frame time, ms ({vwb.adapter().split(' [')[0]})")
    ax.set_ylabel("RMS ΔE*uv against the converged reference")
    ax.set_title("slice spacing sweep (labels: spacing in voxels)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(a.out, dpi=120)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
