#!/usr/bin/env python3
"""Load time per volume format: the CT head sample converted to NIfTI (.nii, .nii.gz),
MetaImage (.mhd + .raw, .mha with zlib) and a DICOM series (one explicit VR little endian
file per axial slice, written byte by byte here, independently of vwb's own writer) by
this script, each loaded by
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


def dicom_element(group: int, element: int, vr: str, value: bytes) -> bytes:
    """One explicit VR little endian element (values padded to even length)."""
    if len(value) % 2:
        value += b"\0" if vr in ("UI", "OB") else b" "
    if vr in ("OB", "OW", "SQ", "UN", "UT"):
        return struct.pack("<HH2sHI", group, element, vr.encode(), 0, len(value)) + value
    return struct.pack("<HH2sH", group, element, vr.encode(), len(value)) + value


def dicom_slice(k: int, pixels: bytes) -> bytes:
    """Axial slice k of the CT head as a CT image storage file."""
    e = dicom_element
    ct_storage = b"1.2.840.10008.5.1.4.1.1.2"
    instance = f"1.2.826.0.1.3680043.2.1125.7.{k + 1}".encode()
    meta = b"".join([
        e(0x0002, 0x0001, "OB", b"\0\1"), e(0x0002, 0x0002, "UI", ct_storage),
        e(0x0002, 0x0003, "UI", instance), e(0x0002, 0x0010, "UI", b"1.2.840.10008.1.2.1"),
        e(0x0002, 0x0012, "UI", b"1.2.826.0.1.3680043.2.1125.7"),
    ])
    us = lambda v: struct.pack("<H", v)
    body = b"".join([
        e(0x0008, 0x0016, "UI", ct_storage), e(0x0008, 0x0018, "UI", instance),
        e(0x0008, 0x0060, "CS", b"CT"),
        e(0x0020, 0x000E, "UI", b"1.2.826.0.1.3680043.2.1125.7"),
        e(0x0020, 0x0013, "IS", str(k + 1).encode()),
        e(0x0020, 0x0032, "DS", f"0\\0\\{k * SPACING[2]}".encode()),
        e(0x0020, 0x0037, "DS", b"1\\0\\0\\0\\1\\0"),
        e(0x0028, 0x0002, "US", us(1)), e(0x0028, 0x0004, "CS", b"MONOCHROME2"),
        e(0x0028, 0x0010, "US", us(DIMS[1])), e(0x0028, 0x0011, "US", us(DIMS[0])),
        e(0x0028, 0x0030, "DS", f"{SPACING[1]}\\{SPACING[0]}".encode()),
        e(0x0028, 0x0100, "US", us(16)), e(0x0028, 0x0101, "US", us(16)),
        e(0x0028, 0x0102, "US", us(15)), e(0x0028, 0x0103, "US", us(1)),
        e(0x0028, 0x1052, "DS", b"0"), e(0x0028, 0x1053, "DS", b"1"),
        e(0x7FE0, 0x0010, "OW", pixels),
    ])
    group_length = e(0x0002, 0x0000, "UL", struct.pack("<I", len(meta)))
    return b"\0" * 128 + b"DICM" + group_length + meta + body


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
        series = t / "ct_dicom"
        series.mkdir()
        plane = DIMS[0] * DIMS[1] * 2
        for k in range(DIMS[2]):
            (series / f"IM{k:04d}").write_bytes(dicom_slice(k, samples[k * plane:(k + 1) * plane]))
        reference = None
        raw = data / "ct_cranium_256x256x108_int16.raw"
        for label, path, extra in [("NRRD (.nhdr + .raw)", nhdr, raw), ("NIfTI-1 .nii", t / "ct.nii", None),
                                   ("NIfTI-1 .nii.gz", t / "ct.nii.gz", None),
                                   ("MetaImage .mhd + .raw", t / "ct.mhd", t / "ct.raw"),
                                   ("MetaImage .mha, zlib", t / "ct.mha", None),
                                   (f"DICOM series ({DIMS[2]} files, a folder)", series, None)]:
            secs, text = timed(vwb, env, path)
            size = (sum(f.stat().st_size for f in path.iterdir()) if path.is_dir()
                    else path.stat().st_size + (extra.stat().st_size if extra else 0))
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
