"""Shared helpers of the benchmark scripts: the machine line, the environment that
pins lavapipe, and rewriting a marked block of a Markdown file."""

import argparse
import os
import platform
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
LAVAPIPE_ICD = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json"


def cpu_model() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def machine_line() -> str:
    return f"{cpu_model()}, {os.cpu_count()} cores, {platform.system()} {platform.release()}"


def round_order(items: list, r: int) -> list:
    """The order of round `r` of an interleaved benchmark: `items` as given in even
    rounds, reversed in odd ones, so that no item always runs first."""
    return items if r % 2 == 0 else items[::-1]


def bench_parser(doc: str, block: str, frames: int, rounds: int, presets: str):
    """The options every interleaved-rounds benchmark takes (the binary, image size,
    frames per render, rounds, presets, --gpu, the docs block and --print-only)."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=default_vwb())
    ap.add_argument("--size", default="512x512")
    ap.add_argument("--frames", type=int, default=frames)
    ap.add_argument("--rounds", type=int, default=rounds)
    ap.add_argument("--preset", action="append", help=f"repeatable (default: {presets})")
    ap.add_argument("--gpu", action="store_true")
    ap.add_argument("--block", default=block)
    ap.add_argument("--print-only", action="store_true")
    return ap


def publish(command: str, how: str, adapter: str, gpu: bool, rows: list, block: str,
            print_only: bool) -> None:
    """The block of a benchmark table (command, how it was timed, machine, adapter,
    rows), printed and, unless `print_only`, written to `block` in docs/perf.md."""
    threads = os.environ.get("LP_NUM_THREADS")
    text = (
        f"Command: `{command}` — {how}\n\n"
        f"- Machine: {machine_line()}\n"
        f"- Adapter: {adapter}" + (f" (LP_NUM_THREADS={threads})" if threads and not gpu else "")
        + "\n\n" + "\n".join(rows) + "\n"
    )
    print(text)
    if not print_only:
        write_block(REPO / "docs/perf.md", block, text)


def vwb_env(gpu: bool) -> dict:
    """Environment for running vwb: lavapipe pinned with 2 threads unless `gpu`."""
    env = dict(os.environ)
    env.setdefault("XDG_RUNTIME_DIR", "/tmp")
    if not gpu:
        env["VK_DRIVER_FILES"] = LAVAPIPE_ICD
        env.setdefault("LP_NUM_THREADS", "2")
    return env


def default_vwb() -> str:
    """The most recently built `vwb` (release or debug): an older release binary left
    from before a change would measure the old code."""
    built = [p for p in (REPO / "target" / b / "vwb" for b in ("release", "debug")) if p.exists()]
    if built:
        return str(max(built, key=lambda p: p.stat().st_mtime))
    return str(REPO / "target/release/vwb")


def write_block(doc: Path, name: str, block: str) -> None:
    """Replaces the text between <!-- BEGIN name --> and <!-- END name --> (appends the
    block when the markers are missing)."""
    text = doc.read_text() if doc.exists() else "# Performance\n"
    begin, end = f"<!-- BEGIN {name} -->", f"<!-- END {name} -->"
    if begin in text and end in text:
        pre, rest = text.split(begin, 1)
        _, post = rest.split(end, 1)
        text = f"{pre}{begin}\n{block}\n{end}{post}"
    else:
        text = text.rstrip() + f"\n\n{begin}\n{block}\n{end}\n"
    doc.write_text(text)
