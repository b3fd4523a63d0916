# Sourced by the bench scripts that run on the CPU Vulkan device: pins lavapipe (2
# threads) unless VWB_TEST_GPU=1 or VK_DRIVER_FILES is already set.
lvp=$(ls /usr/share/vulkan/icd.d/lvp_icd.*.json 2>/dev/null | head -n 1 || true)
if [ "${VWB_TEST_GPU:-0}" != 1 ] && [ -z "${VK_DRIVER_FILES:-}" ] && [ -n "$lvp" ]; then
    export VK_DRIVER_FILES="$lvp"
fi
export LP_NUM_THREADS="${LP_NUM_THREADS:-2}"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
