#!/usr/bin/env python3
"""Writes presets/data/nuclei_labels.nrrd: a u8 label volume beside the nuclei sample
(skimage cells3d nuclei channel, 256×256×60 u16, BSD-3), for clip.labels.

Labels: the data normalised to its range (as vwb normalises it), smoothed by a 3×3×3
box filter, thresholded at 0.15 (the lower edge of the nuclei in presets/nuclei.ron),
split into 6-connected components; components are numbered by size, largest first
(1, 2, …); those beyond 254 and fragments under 50 voxels get 255; 0 is background.

Rerun: VWB_DATA_DIR=<folder with the sample data> python3 bench/make_nuclei_labels.py
(stdlib only; reads nuclei_fluo_256x256x60_uint16.raw).
"""

import array
import gzip
import os
from collections import deque
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
DATA = Path(os.environ.get("VWB_DATA_DIR", REPO / "../shared/data"))
SRC = DATA / "nuclei_fluo_256x256x60_uint16.raw"
OUT = REPO / "presets/data/nuclei_labels.nrrd"
NX, NY, NZ = 256, 256, 60
THRESHOLD = 0.15
MIN_SIZE = 50


def box3(values):
    """Separable 3-wide box filter with clamped edges, x, then y, then z."""
    strides = (1, NX, NX * NY)
    sizes = (NX, NY, NZ)
    for axis in range(3):
        stride, n = strides[axis], sizes[axis]
        out = [0.0] * len(values)
        for i in range(len(values)):
            c = (i // stride) % n
            lo = values[i - stride] if c > 0 else values[i]
            hi = values[i + stride] if c < n - 1 else values[i]
            out[i] = (lo + values[i] + hi) / 3.0
        values = out
    return values


def main():
    raw = array.array("H")
    raw.frombytes(SRC.read_bytes())
    if os.sys.byteorder != "little":
        raw.byteswap()
    assert len(raw) == NX * NY * NZ, len(raw)
    lo, hi = min(raw), max(raw)
    norm = [(v - lo) / (hi - lo) for v in raw]
    smooth = box3(norm)
    fg = bytearray(1 if v >= THRESHOLD else 0 for v in smooth)
    comp = [0] * len(fg)
    sizes = []
    for start in range(len(fg)):
        if not fg[start] or comp[start]:
            continue
        label = len(sizes) + 1
        comp[start] = label
        queue = deque([start])
        size = 0
        while queue:
            i = queue.popleft()
            size += 1
            x, y, z = i % NX, (i // NX) % NY, i // (NX * NY)
            for ok, j in (
                (x > 0, i - 1), (x < NX - 1, i + 1),
                (y > 0, i - NX), (y < NY - 1, i + NX),
                (z > 0, i - NX * NY), (z < NZ - 1, i + NX * NY),
            ):
                if ok and fg[j] and not comp[j]:
                    comp[j] = label
                    queue.append(j)
        sizes.append(size)
    order = sorted(range(len(sizes)), key=lambda k: -sizes[k])
    rank = {}
    for r, k in enumerate(order):
        rank[k + 1] = r + 1 if r < 254 and sizes[k] >= MIN_SIZE else 255
    labels = bytes(rank[c] if c else 0 for c in comp)
    header = (
        "NRRD0004\n"
        "# nuclei labels for vwb (bench/make_nuclei_labels.py): 6-connected components of the smoothed nuclei\n"
        "# sample above 0.15 of its range, 1 = largest; 255 = fragments; derived from skimage cells3d (BSD-3)\n"
        "type: uint8\ndimension: 3\n"
        f"sizes: {NX} {NY} {NZ}\n"
        "spacings: 0.26 0.26 0.29\nencoding: gzip\n\n"
    )
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_bytes(header.encode() + gzip.compress(labels, compresslevel=9, mtime=0))
    big = [sizes[k] for k in order[:10]]
    print(f"wrote {OUT} ({OUT.stat().st_size} bytes); {len(sizes)} components, largest {big}")


if __name__ == "__main__":
    main()
