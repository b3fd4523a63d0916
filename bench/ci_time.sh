#!/usr/bin/env bash
# How long a cold CI run takes, per phase: clones the repository's HEAD beside it (into
# ../vwb-ci-time, so ../shared is the same), runs `.ci/run` there as CI does (no target/,
# the crates from Cargo's cache), and prints the phase times that scripts/test reports
# and the total, with the machine. 20–45 minutes on 2 cores. docs/perf.md, "The test
# suite's time", quotes it.
#
#   bash bench/ci_time.sh [REV]    # REV: the commit to time (default HEAD)
set -euo pipefail
cd "$(dirname "$0")/.."
export VWB_DATA_DIR="${VWB_DATA_DIR:-$PWD/../shared/data}"
dir="$(cd .. && pwd)/vwb-ci-time"
rm -rf "$dir"
rev=$(git rev-parse --verify "${1:-HEAD}^{commit}")
git clone -q . "$dir"
cd "$dir"
git checkout -q "$rev"
echo "commit $(git rev-parse --short HEAD), $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
start=$SECONDS
set +e
CI=true bash .ci/run > ci.log 2>&1
rc=$?
set -e
grep "scripts/test phases" ci.log || true
echo "total $((SECONDS - start)) s, exit status $rc (log: $dir/ci.log)"
exit $rc
