#!/usr/bin/env bash
# The integration suite on a GPU machine without a Rust toolchain, in one device call:
# what has to travel (the test binary, the debug `vwb` the CLI tests run, the sample
# data) packed small enough to go beside the working tree (64 MiB in all: about 51 MB
# packed), then run there with the best adapter.
#
#   bash bench/gpu_suite.sh pack DIR          # here, after `cargo test --no-run`
#   bash bench/gpu_suite.sh run DIR OUT [FILTER...]   # there, from the repo root
#   GPU_STEPS="backends perf" bash bench/gpu_suite.sh bench DIR OUT   # bench/gpu.sh's steps
#
# pack: strips and gzips the newest integration-test binary and target/debug/vwb and
# gzips the sample data (VWB_DATA_DIR, else ../shared/data) into DIR (an ignored
# folder of the repository, e.g. .gpu-suite: carry it), with the path the binaries
# were built in. run: unpacks them, puts `vwb` where the CLI tests look for it
# (target/debug/vwb under the build path, unless one is there; the build path is linked
# to this checkout when it does not exist) and runs the suite with VWB_TEST_GPU=1 (the best adapter), 8 threads,
# under a 400 s limit (SUITE_THREADS, SUITE_LIMIT override both); OUT gets suite.log and summary.txt (the result lines and the
# failures). The test of the window under Xvfb needs a display and is skipped.
set -uo pipefail
cd "$(dirname "$0")/.."
mode=${1:-}
dir=${2:?usage: bash bench/gpu_suite.sh pack DIR | run DIR OUT [FILTER...] | bench DIR OUT}
case $mode in
pack)
    mkdir -p "$dir"
    bin=$(ls -t target/debug/deps/integration-* 2>/dev/null | grep -v '\.d$' | head -1)
    [ -n "$bin" ] && [ -x target/debug/vwb ] || {
        echo "no test binary: run cargo test --locked --test integration --no-run first" >&2
        exit 1
    }
    for f in "$bin:integration" "target/debug/vwb:vwb"; do
        src=${f%%:*} name=${f##*:}
        strip -o "$dir/$name" "$src" && gzip -6 -f "$dir/$name"
    done
    data=${VWB_DATA_DIR:-../shared/data}
    tar czf "$dir/data.tar.gz" -C "$data" .
    pwd >"$dir/build_path"
    du -sh "$dir"
    ;;
bench)
    # the pack's debug vwb and test binary through bench/gpu.sh (the GPU's time does
    # not depend on the build profile): GPU_STEPS as there, default "backends"
    out=${3:?OUT}
    mkdir -p "$out" /tmp/vwb-suite/data
    gunzip -c "$dir/integration.gz" >/tmp/vwb-suite/integration
    gunzip -c "$dir/vwb.gz" >/tmp/vwb-suite/vwb
    chmod +x /tmp/vwb-suite/integration /tmp/vwb-suite/vwb
    tar xzf "$dir/data.tar.gz" -C /tmp/vwb-suite/data
    GPU_STEPS=${GPU_STEPS:-backends} bash bench/gpu.sh /tmp/vwb-suite/vwb \
        /tmp/vwb-suite/integration /tmp/vwb-suite/data "$out"
    ;;
run)
    out=${3:?OUT}
    shift 3
    mkdir -p "$out" /tmp/vwb-suite/data
    gunzip -c "$dir/integration.gz" >/tmp/vwb-suite/integration
    chmod +x /tmp/vwb-suite/integration
    tar xzf "$dir/data.tar.gz" -C /tmp/vwb-suite/data
    build=$(cat "$dir/build_path")
    if [ ! -e "$build" ]; then
        mkdir -p "$(dirname "$build")" && ln -s "$PWD" "$build"
    fi
    mkdir -p "$build/target/debug"
    if [ ! -x "$build/target/debug/vwb" ]; then
        gunzip -c "$dir/vwb.gz" >"$build/target/debug/vwb"
        chmod +x "$build/target/debug/vwb"
    fi
    export VWB_DATA_DIR=/tmp/vwb-suite/data VWB_TEST_GPU=1 XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
    unset LP_NUM_THREADS
    t0=$SECONDS
    (cd "$build" && timeout "${SUITE_LIMIT:-400}" /tmp/vwb-suite/integration --test-threads="${SUITE_THREADS:-8}" --skip window_screenshot_under_xvfb "$@") \
        >"$out/suite.log" 2>&1
    rc=$?
    {
        echo "rc=$rc in $((SECONDS - t0)) s"
        grep -E "^test result|^failures:|^    [a-z_]+::|panicked" "$out/suite.log" | head -80
    } | tee "$out/summary.txt"
    ;;
*)
    echo "usage: bash bench/gpu_suite.sh pack DIR | run DIR OUT [FILTER...] | bench DIR OUT" >&2
    exit 2
    ;;
esac
