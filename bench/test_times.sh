#!/usr/bin/env bash
# Where the integration suite's time goes: runs the integration-test binary as
# `cargo test` does (2 test threads, lavapipe pinned, LP_NUM_THREADS=2) with libtest's
# per-test times, and prints the wall time, the sum over tests and the slowest tests.
# docs/perf.md, "The test suite's time", quotes it. About 10 minutes on 2 cores.
#
#   bash bench/test_times.sh [N]      # N slowest tests (default 15)
# RUSTC_BOOTSTRAP=1 lets the stable test harness take `-Z unstable-options
# --report-time`; nothing is compiled with it.
set -euo pipefail
cd "$(dirname "$0")/.."
source bench/lavapipe.sh
export VWB_DATA_DIR="${VWB_DATA_DIR:-$PWD/../shared/data}"
bin=$(cargo test --locked --test integration --no-run --message-format=json 2>/dev/null |
    python3 -c 'import json,sys
for l in sys.stdin:
    m = json.loads(l)
    if m.get("reason") == "compiler-artifact" and m["target"]["name"] == "integration" and m.get("executable"):
        print(m["executable"])')
log=$(mktemp)
RUSTC_BOOTSTRAP=1 "$bin" -Z unstable-options --report-time --test-threads=2 >"$log" 2>&1 || {
    tail -40 "$log"; exit 1; }
echo "commit $(git rev-parse --short HEAD), $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
python3 - "$log" "${1:-15}" <<'PY'
import re, sys
times = {}
for line in open(sys.argv[1]):
    m = re.match(r"test (\S+) \.\.\. ok <([\d.]+)s>", line)
    if m:
        times[m.group(1)] = float(m.group(2))
    m = re.search(r"finished in ([\d.]+)s", line)
    if m:
        wall = float(m.group(1))
print(f"wall {wall:.1f} s, sum over {len(times)} tests {sum(times.values()):.0f} s")
for name, t in sorted(times.items(), key=lambda kv: -kv[1])[: int(sys.argv[2])]:
    print(f"{t:8.1f} s  {name}")
PY
