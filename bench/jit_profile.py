#!/usr/bin/env python3
"""Where lavapipe's JIT-compiled shader code spends a frame: a `perf` profile of
`vwb bench`, with the hot code read back from the process and disassembled.

llvmpipe compiles shaders to machine code at run time, so `perf report` shows only
"[JIT]". This samples the running benchmark's instruction pointers, copies the
executable mapping that holds most of them (`--mappings N`: the N hottest) out of /proc/PID/mem, disassembles it with
objdump and prints each function of the code (split at `ret`) with its share of the
samples, and writes the annotated disassembly (samples per instruction) to
`--annotate`. The texture fetches show as their own functions (a trilinear 3D
sample is a run of 8 `vpgatherdd`s: the `gathers` column counts them).

Needs root (or ptrace rights), `perf` (Debian: linux-perf) and `objdump`. Usage:

    python3 bench/jit_profile.py --preset presets/ct_shade_none.ron \\
        --bench-arg=--early-termination --bench-arg=0.99
"""
import argparse
import collections
import os
import re
import subprocess
import sys
import tempfile
import time


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--vwb", default="target/debug/vwb")
    ap.add_argument("--preset", required=True)
    ap.add_argument("--backend", default="compute")
    ap.add_argument("--size", default="512x512")
    ap.add_argument("--warm", type=float, default=12.0, help="seconds before sampling")
    ap.add_argument("--seconds", type=float, default=6.0, help="seconds sampled")
    ap.add_argument("--bench-arg", action="append", default=[])
    ap.add_argument("--annotate", default="/tmp/vwb_jit.s")
    ap.add_argument("--mappings", type=int, default=1,
                    help="how many code mappings to read, hottest first (a frame of several "
                         "shaders, e.g. DOS's slice and update passes, spreads over several)")
    a = ap.parse_args()
    env = dict(os.environ)
    env.setdefault("LP_NUM_THREADS", "2")
    with tempfile.TemporaryDirectory() as d:
        cmd = [a.vwb, "bench", "--preset", a.preset, "--frames", "100000", "--warmup", "2",
               "--size", a.size, "--backend", a.backend, "-o", os.path.join(d, "b.csv")]
        bench = subprocess.Popen(cmd + a.bench_arg, env=env, stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL)
        try:
            time.sleep(a.warm)
            if bench.poll() is not None:
                sys.exit(f"{a.vwb} bench ended early (rc {bench.returncode})")
            data = os.path.join(d, "perf.data")
            subprocess.run(["perf", "record", "-F", "2000", "-p", str(bench.pid), "-o", data,
                            "--", "sleep", str(a.seconds)], check=True,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            ips = [int(l.split()[0], 16) for l in subprocess.run(
                ["perf", "script", "-i", data, "-F", "ip"], check=True, capture_output=True,
                text=True).stdout.splitlines() if l.strip()]
            maps = []
            with open(f"/proc/{bench.pid}/maps") as f:
                for line in f:
                    lo, hi = (int(x, 16) for x in line.split()[0].split("-"))
                    maps.append((lo, hi))
            per_map = collections.Counter()
            for ip in ips:
                for lo, hi in maps:
                    if lo <= ip < hi:
                        per_map[(lo, hi)] += 1
                        break
            codes = []
            with open(f"/proc/{bench.pid}/mem", "rb") as f:
                for (lo, hi), _ in per_map.most_common(a.mappings):
                    f.seek(lo)
                    codes.append((lo, hi, f.read(hi - lo)))
        finally:
            bench.kill()
            bench.wait()
        for k, (start, end, code) in enumerate(codes):
            annotate = a.annotate if k == 0 else f"{a.annotate}.{k}"
            report(a, d, ips, start, end, code, annotate, k)


def report(a, d, ips, start, end, code, annotate, k):
    """Disassembles one code mapping and prints its functions' shares."""
    binfile = os.path.join(d, "jit.bin")
    with open(binfile, "wb") as f:
        f.write(code)
    asm = subprocess.run(["objdump", "-D", "-b", "binary", "-mi386:x86-64", binfile],
                         check=True, capture_output=True, text=True).stdout
    hits = collections.Counter(ip - start for ip in ips if start <= ip < end)
    lines, funcs, cur = [], [], None
    for line in asm.splitlines():
        m = re.match(r"\s*([0-9a-f]+):\s+(.*)", line)
        if not m:
            continue
        at, n = int(m.group(1), 16), hits.get(int(m.group(1), 16), 0)
        lines.append(f"{n:6d} {line}")
        cur = cur or [at, at, 0, 0, 0]
        cur[1], cur[2], cur[3] = at, cur[2] + n, cur[3] + 1
        cur[4] += "gather" in m.group(2)
        if m.group(2).rstrip().endswith("ret"):
            funcs.append(cur)
            cur = None
    if cur:
        funcs.append(cur)
    with open(annotate, "w") as f:
        f.write("\n".join(lines) + "\n")
    inside = sum(hits.values())
    print(f"{a.preset} ({a.backend}, {a.size}, {' '.join(a.bench_arg)}): {len(ips)} samples, "
          f"{inside / max(len(ips), 1):.1%} in code mapping {k} (hottest first)")
    print("| function (offsets) | instructions | gathers | share of the mapping's samples |")
    print("|---|---:|---:|---:|")
    for lo, hi, n, count, gathers in funcs:
        if n > inside * 0.01:
            print(f"| {lo:#x}–{hi:#x} | {count} | {gathers} | {n / inside:.1%} |")
    print(f"annotated disassembly: {annotate}")

if __name__ == "__main__":
    main()
