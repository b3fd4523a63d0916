#!/usr/bin/env python3
"""Writes presets/data/demo_labels.nrrd: a u8 label volume beside the embedded demo
(the VolPack MRI head, 128×128×84), for classify.labels.

Labels, from the demo's raw values (0..255) smoothed by a 5×5×5 box filter (so that
the regions are compact, as a segmentation's are, rather than speckled by noise), and
position:
  0  background (value < 30)
  1  soft tissue (30 ≤ value < 100), left half (x < 64)
  2  soft tissue, right half
  3  dense tissue (value ≥ 100)
Rerun: python3 bench/make_demo_labels.py (reads the demo's gzip NRRD; stdlib only).
"""

import gzip
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SRC = REPO / "render/data/demo_mri_head.nrrd"
OUT = REPO / "presets/data/demo_labels.nrrd"
NX, NY, NZ = 128, 128, 84


def box_filter(values, r):
    """Separable (2r+1)-wide box filter with clamped edges, x, then y, then z."""
    strides = (1, NX, NX * NY)
    sizes = (NX, NY, NZ)
    for axis in range(3):
        stride, n = strides[axis], sizes[axis]
        out = [0.0] * len(values)
        for i in range(len(values)):
            c = (i // stride) % n
            acc = 0.0
            for k in range(-r, r + 1):
                j = min(max(c + k, 0), n - 1)
                acc += values[i + (j - c) * stride]
            out[i] = acc / (2 * r + 1)
        values = out
    return values


def main():
    raw = SRC.read_bytes()
    header_end = raw.index(b"\n\n") + 2
    data = gzip.decompress(raw[header_end:])
    assert len(data) == NX * NY * NZ, len(data)
    smooth = box_filter(list(data), 2)
    labels = bytearray(len(data))
    for i, v in enumerate(smooth):
        if v < 30:
            continue
        if v >= 100:
            labels[i] = 3
        else:
            labels[i] = 1 if (i % NX) < 64 else 2
    header = (
        "NRRD0004\n"
        "# label volume for the vwb demo (bench/make_demo_labels.py): 0 background, 1 left soft tissue,\n"
        "# 2 right soft tissue, 3 dense tissue; derived from the VolPack MRI head (BSD-3, see render/data/LICENSE-demo.md)\n"
        "type: uint8\ndimension: 3\n"
        f"sizes: {NX} {NY} {NZ}\n"
        "spacings: 1 1 1\nencoding: gzip\n\n"
    )
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_bytes(header.encode() + gzip.compress(bytes(labels), mtime=0))
    print(f"wrote {OUT} ({OUT.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
