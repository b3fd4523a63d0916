#!/usr/bin/env python3
"""OME-Zarr: load time and the stored level-of-detail pyramid, written by the reference
implementation (zarr-python), not by vwb.

1. Load time (block `ome-zarr` of docs/data.md): the CT head sample (256×256×108 int16)
   as NGFF 0.4 in Zarr v2 (Blosc zstd with byte shuffle, 64³ chunks, "/" keys: what
   ome-zarr-py writes) and as NGFF 0.5 in Zarr v3 (sharded, zstd), each with two
   coarser levels (2×2×2 means), loaded by `vwb info --volume F` (process start, load
   of level 0, value range and histogram), median of 5 runs.
2. The pyramid under a GPU memory budget (block `ome-zarr-pyramid`): the CT head
   upsampled 2× along every axis (512×512×216 int16, 108 MiB) as a 3-level OME-Zarr
   (level 1 is then the CT head itself) and as NRRD. `vwb render --preset
   presets/ct_head.ron --volume F --size 256x256` wall time to the PNG and peak memory
   (GNU time's maximum RSS), without a budget and with VWB_GPU_MEMORY_LIMIT=64 MiB: the
   NRRD is read whole and averaged to a 1/2 level, the OME-Zarr reads only its stored
   level 1; with the bricks in view refined (the default) and without (VWB_LOD_REFINE=0).
   Images compared in 8-bit RGB.

Needs numpy, pillow and zarr (`pip install numpy pillow zarr`):

    python bench/ome_zarr.py [--vwb target/release/vwb] [--runs 5] [--print-only]
"""

import argparse
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numcodecs
import numpy as np
import zarr
from PIL import Image
from zarr.codecs import ZstdCodec

from doclib import REPO, default_vwb, machine_line, vwb_env, write_block

SPACING = (0.9570312, 0.9570312, 1.5)  # x, y, z


def pyramid(a: np.ndarray, n: int) -> list:
    """`a` and n − 1 levels of 2×2×2 means (odd ends dropped), in a's type."""
    out = [a]
    for _ in range(n - 1):
        b = out[-1].astype(np.float64)
        z, y, x = (s // 2 * 2 for s in b.shape)
        b = b[:z, :y, :x].reshape(z // 2, 2, y // 2, 2, x // 2, 2).mean(axis=(1, 3, 5))
        out.append(np.round(b).astype(a.dtype))
    return out


def multiscales(n: int, spacing, version: str | None) -> list:
    sx, sy, sz = spacing
    m = {
        "axes": [{"name": k, "type": "space", "unit": "millimeter"} for k in "zyx"],
        "datasets": [{"path": str(i), "coordinateTransformations": [
            {"type": "scale", "scale": [sz * 2**i, sy * 2**i, sx * 2**i]}]} for i in range(n)],
    }
    if version:
        m["version"] = version
    return [m]


def write(path: Path, levels: list, spacing, v3: bool) -> None:
    g = zarr.open_group(str(path), mode="w", zarr_format=3 if v3 else 2)
    for i, level in enumerate(levels):
        if v3:
            chunks = tuple(min(s, 32) for s in level.shape)
            arr = g.create_array(str(i), shape=level.shape, dtype=level.dtype, chunks=chunks,
                                 shards=tuple(4 * c for c in chunks),
                                 compressors=ZstdCodec(level=3), dimension_names=["z", "y", "x"])
        else:
            arr = g.create_array(str(i), shape=level.shape, dtype=level.dtype,
                                 chunks=tuple(min(s, 64) for s in level.shape),
                                 compressors=numcodecs.Blosc(cname="zstd", clevel=5,
                                                             shuffle=numcodecs.Blosc.SHUFFLE),
                                 chunk_key_encoding={"name": "v2", "separator": "/"})
        arr[:] = level
    if v3:
        g.attrs["ome"] = {"version": "0.5", "multiscales": multiscales(len(levels), spacing, None)}
    else:
        g.attrs["multiscales"] = multiscales(len(levels), spacing, "0.4")


def nrrd(path: Path, a: np.ndarray, spacing) -> None:
    z, y, x = a.shape
    head = (f"NRRD0004\ntype: int16\ndimension: 3\nsizes: {x} {y} {z}\nendian: little\n"
            f"encoding: raw\nspacings: {spacing[0]} {spacing[1]} {spacing[2]}\n\n")
    path.write_bytes(head.encode() + a.astype("<i2").tobytes())


def size_mib(path: Path) -> float:
    files = path.rglob("*") if path.is_dir() else [path]
    return sum(f.stat().st_size for f in files if f.is_file()) / 2**20


def run(cmd, env, runs):
    """Median wall seconds, the largest peak RSS (MiB) and the last run's stderr."""
    secs, rss, err = [], [], ""
    for _ in range(runs):
        start = time.perf_counter()
        p = subprocess.run(["/usr/bin/time", "-v", *cmd], cwd=REPO, env=env,
                           capture_output=True, text=True)
        secs.append(time.perf_counter() - start)
        if p.returncode != 0:
            sys.exit(f"{' '.join(map(str, cmd))} failed:\n{p.stderr}")
        m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr)
        rss.append(int(m.group(1)) / 1024 if m else float("nan"))
        err = p.stderr
    return statistics.median(secs), max(rss), err


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=default_vwb())
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--print-only", action="store_true")
    a = ap.parse_args()
    env = vwb_env(False)
    data = Path(env.get("VWB_DATA_DIR", REPO.parent / "shared" / "data"))
    ct = np.fromfile(data / "ct_cranium_256x256x108_int16.raw", dtype="<i2").reshape(108, 256, 256)
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        # 1. load time of the CT head
        rows, reference = [], None
        nhdr = data / "ct_cranium_256x256x108_int16.nhdr"
        write(t / "ct_v2.ome.zarr", pyramid(ct, 3), SPACING, v3=False)
        write(t / "ct_v3.ome.zarr", pyramid(ct, 3), SPACING, v3=True)
        for label, path, mib in [
            ("NRRD (.nhdr + .raw), for comparison", nhdr,
             size_mib(nhdr) + size_mib(data / "ct_cranium_256x256x108_int16.raw")),
            ("OME-Zarr NGFF 0.4, Zarr v2, Blosc zstd, 3 levels", t / "ct_v2.ome.zarr", None),
            ("OME-Zarr NGFF 0.5, Zarr v3, sharded zstd, 3 levels", t / "ct_v3.ome.zarr", None),
        ]:
            secs, _, _ = run([a.vwb, "info", "--volume", str(path)], env, a.runs)
            out = subprocess.run([a.vwb, "info", "--volume", str(path)], cwd=REPO, env=env,
                                 capture_output=True, text=True).stdout
            rng = next(l for l in out.splitlines() if l.startswith("value range"))
            dims = next(l for l in out.splitlines() if l.startswith("dims"))
            reference = reference or (rng, dims)
            same = "yes" if (rng, dims) == reference else "NO"
            mib = mib if mib is not None else size_mib(path)
            rows.append(f"| {label} | {mib:.1f} | {secs * 1e3:.0f} | {same} |")
        load_block = "\n".join([
            f"Machine: {machine_line()}. `vwb info --volume F` wall time (process start, load of "
            f"level 0, value range and histogram), median of {a.runs} runs; the CT head sample "
            "written by zarr-python " + zarr.__version__ + " (`python bench/ome_zarr.py`).",
            "",
            "| store | files (MiB, all levels) | load (ms) | same dims and value range |",
            "|---|---:|---:|---|",
            *rows,
        ])
        # 2. the pyramid of a larger volume under a budget
        big = ct.repeat(2, 0).repeat(2, 1).repeat(2, 2)
        spacing = tuple(s / 2 for s in SPACING)
        write(t / "big.ome.zarr", pyramid(big, 3), spacing, v3=False)
        nrrd(t / "big.nrrd", big, spacing)
        del big
        budget = 64 << 20
        rows, images = [], {}
        for label, path in [("NRRD", t / "big.nrrd"), ("OME-Zarr, 3 levels", t / "big.ome.zarr")]:
            # no budget; the budget with the coarser level alone (VWB_LOD_REFINE=0); the
            # budget with the bricks in view refined (the default)
            for limit, refine in ((None, True), (budget, False), (budget, True)):
                e = dict(env)
                if limit:
                    e["VWB_GPU_MEMORY_LIMIT"] = str(limit)
                if not refine:
                    e["VWB_LOD_REFINE"] = "0"
                png = t / f"{path.stem}_{limit or 0}_{int(refine)}.png"
                secs, rss, err = run([a.vwb, "render", "--preset", "presets/ct_head.ron",
                                      "--volume", str(path), "--size", "256x256", "-o", str(png)],
                                     e, a.runs)
                img = np.asarray(Image.open(png).convert("RGB")).astype(np.int16)
                images[(label, limit, refine)] = img
                shown = next((l.split("note: ", 1)[1] for l in err.splitlines()
                              if "showing a 1/" in l), "the full volume")
                shown = re.sub(r": the volume needs.*", "", shown)
                if limit:
                    shown += ", bricks in view refined" if refine else ", not refined"
                full = images[(label, None, True)]
                diff = np.abs(img - full)
                rows.append(f"| {label} | {size_mib(path):.0f} | "
                            f"{'none' if not limit else f'{limit >> 20} MiB'} | {shown} | "
                            f"{secs * 1e3:.0f} | {rss:.0f} | {diff.mean():.2f} / {diff.max()} |")
        d_full = np.abs(images[("NRRD", None, True)] - images[("OME-Zarr, 3 levels", None, True)]).max()
        d_level = np.abs(images[("NRRD", budget, False)]
                         - images[("OME-Zarr, 3 levels", budget, False)]).max()
        pyramid_block = "\n".join([
            f"Machine: {machine_line()}. The CT head upsampled 2× along every axis (512×512×216 "
            "int16, 108 MiB; level 1 of the pyramid is then the CT head itself), written as NRRD "
            "and as a 3-level OME-Zarr (NGFF 0.4, Blosc zstd) by `python bench/ome_zarr.py`. "
            "`vwb render --preset presets/ct_head.ron --volume F --size 256x256` on lavapipe: "
            f"wall time from process start to the PNG (median of {a.runs}) and peak resident "
            "memory. With the budget, the NRRD is read whole, stored in 16 bits, still over "
            "the budget, and averaged to a 1/2 level; the OME-Zarr reads only its stored level 1. "
            "Then, by default, the bricks in view are refined before the image (headless: all "
            "in one frame), from the NRRD in memory or from the OME-Zarr's level 0 region by "
            "region; `VWB_LOD_REFINE=0` shows the coarser level alone. Last column: mean and "
            "largest 8-bit difference to the same file's image without a budget.",
            "",
            "| file | MiB on disk | GPU budget | shown | first image (ms) | peak RSS (MiB) | 8-bit difference to no budget (mean / largest) |",
            "|---|---:|---|---|---:|---:|---|",
            *rows,
            "",
            f"Largest 8-bit difference between the NRRD and OME-Zarr images: {d_full} without a "
            f"budget (the same level 0), {d_level} with the budget and no refinement (averaged "
            "1/2 level against the stored one).",
        ])
    if not a.print_only:
        write_block(REPO / "docs" / "data.md", "ome-zarr", load_block)
        write_block(REPO / "docs" / "data.md", "ome-zarr-pyramid", pyramid_block)
    print(load_block)
    print()
    print(pyramid_block)


if __name__ == "__main__":
    main()
