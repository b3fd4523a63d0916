#!/usr/bin/env python3
"""Load time per volume format: the CT head sample converted to NIfTI (.nii, .nii.gz)
and MetaImage (.mhd + .raw, .mha with zlib) by this script, each loaded by
`vwb info --volume F` (process start + load + statistics), median of 5 runs, against
the NRRD it came from. Rewrites the block between <!-- BEGIN formats --> and
<!-- END formats --> in docs/data.md.

    python3 bench/data.py
"""

import gzip
import statistics
import struct
import subprocess
import sys
import tempfile
import time
import zlib
from pathlib import Path

from doclib import REPO, default_vwb, machine_line, vwb_env, write_block

DIMS = (256, 256, 108)
SPACING = (0.9570312, 0.9570312, 1.5)


def nifti1(samples: bytes) -> bytes:
    h = bytearray(352)
    struct.pack_into("<i", h, 0, 348)
    struct.pack_into("<8h", h, 40, 3, *DIMS, 1, 1, 1, 1)
    struct.pack_into("<hh", h, 70, 4, 16)
    struct.pack_into("<8f", h, 76, 1.0, *SPACING, 0, 0, 0, 0)
    struct.pack_into("<f", h, 108, 352.0)
    struct.pack_into("<f", h, 112, 1.0)
    struct.pack_into("<h", h, 254, 1)
    # LPS storage in RAS: x and y negated
    struct.pack_into("<4f", h, 280, -SPACING[0], 0, 0, 0)
    struct.pack_into("<4f", h, 296, 0, -SPACING[1], 0, 0)
    struct.pack_into("<4f", h, 312, 0, 0, SPACING[2], 0)
    h[344:348] = b"n+1\0"
    return bytes(h) + samples


def mhd_header(data_file: str, compressed: bool, size: int) -> str:
    lines = ["ObjectType = Image", "NDims = 3", "BinaryData = True", "BinaryDataByteOrderMSB = False",
             "TransformMatrix = 1 0 0 0 1 0 0 0 1",
             f"ElementSpacing = {SPACING[0]} {SPACING[1]} {SPACING[2]}",
             f"DimSize = {DIMS[0]} {DIMS[1]} {DIMS[2]}", "ElementType = MET_SHORT"]
    if compressed:
        lines += ["CompressedData = True", f"CompressedDataSize = {size}"]
    lines.append(f"ElementDataFile = {data_file}")
    return "\n".join(lines) + "\n"


def timed(vwb, env, path, runs=5):
    out = []
    for _ in range(runs):
        start = time.perf_counter()
        p = subprocess.run([vwb, "info", "--volume", str(path)], cwd=REPO, env=env,
                           capture_output=True, text=True)
        out.append(time.perf_counter() - start)
        if p.returncode != 0:
            sys.exit(f"vwb info --volume {path} failed:\n{p.stderr}")
    return statistics.median(out), p.stdout


def main():
    vwb = default_vwb()
    env = vwb_env(False)
    data = Path(env.get("VWB_DATA_DIR", REPO.parent / "shared" / "data"))
    nhdr = data / "ct_cranium_256x256x108_int16.nhdr"
    samples = (data / "ct_cranium_256x256x108_int16.raw").read_bytes()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        (t / "ct.nii").write_bytes(nifti1(samples))
        (t / "ct.nii.gz").write_bytes(gzip.compress(nifti1(samples), compresslevel=6))
        (t / "ct.raw").write_bytes(samples)
        (t / "ct.mhd").write_text(mhd_header("ct.raw", False, 0))
        z = zlib.compress(samples, 6)
        (t / "ct.mha").write_bytes(mhd_header("LOCAL", True, len(z)).encode() + z)
        reference = None
        raw = data / "ct_cranium_256x256x108_int16.raw"
        for label, path, extra in [("NRRD (.nhdr + .raw)", nhdr, raw), ("NIfTI-1 .nii", t / "ct.nii", None),
                                   ("NIfTI-1 .nii.gz", t / "ct.nii.gz", None),
                                   ("MetaImage .mhd + .raw", t / "ct.mhd", t / "ct.raw"),
                                   ("MetaImage .mha, zlib", t / "ct.mha", None)]:
            secs, text = timed(vwb, env, path)
            size = path.stat().st_size + (extra.stat().st_size if extra else 0)
            rng = next(l for l in text.splitlines() if l.startswith("value range"))
            reference = reference or rng
            same = "yes" if rng == reference else "NO"
            rows.append(f"| {label} | {size / 2**20:.1f} | {secs * 1e3:.0f} | {same} |")
    block = "\n".join([
        f"Machine: {machine_line()}. `vwb info --volume F` wall time (process start, load, value "
        "range and histogram), median of 5 runs; the CT head sample (256×256×108 int16) converted "
        "by `python3 bench/data.py`.",
        "",
        "| format | files (MiB) | load (ms) | same value range |",
        "|---|---:|---:|---|",
        *rows,
    ])
    write_block(REPO / "docs" / "data.md", "formats", block)
    print(block)


if __name__ == "__main__":
    main()
