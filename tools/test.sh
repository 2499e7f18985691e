#!/usr/bin/env bash
# The project's test command (README, .ci/run): everything a new machine
# needs, then every test of the workspace.
set -euo pipefail
cd "$(dirname "$0")/.."
# ONNX Runtime from PyPI into .ort/ (skipped when already there). The ONNX
# tests load it and fail, never skip, when it is missing.
ORT_DYLIB_PATH="$(bash tools/setup-ort.sh | tail -n 1)"
export ORT_DYLIB_PATH
# A Vulkan driver for the `--device vulkan` tests: Mesa's lavapipe runs
# Vulkan on the CPU (skipped when a Vulkan loader and a driver are already
# installed). Those tests fail, never skip, without one.
# Open MPI's `mpirun` for the `--shard auto` test (skipped when already
# installed); that test fails, never skips, without it.
exists() { for pattern in "$@"; do compgen -G "$pattern" > /dev/null && return 0; done; return 1; }
packages=()
if ! exists '/usr/lib/*/libvulkan.so.1' '/usr/lib/libvulkan.so.1' ||
    ! exists '/usr/share/vulkan/icd.d/*.json' '/etc/vulkan/icd.d/*.json'; then
    packages+=(mesa-vulkan-drivers libvulkan1)
fi
command -v mpirun > /dev/null || packages+=(openmpi-bin)
if [ ${#packages[@]} -gt 0 ]; then
    sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
        "${packages[@]}" > /dev/null
fi
cargo test --workspace --locked
# The Python package (python/, pyo3 + maturin) built from this tree into a
# virtual environment, .venv-test/, with its test requirements from PyPI
# (numpy, pytest, PyTorch for mbs.torch), then its tests against the
# mbs-tool binary the Rust tests just built. They fail, never skip, when a
# part is missing.
if [ ! -x .venv-test/bin/python ]; then
    python3 -m venv .venv-test || {
        rm -rf .venv-test
        sudo=""
        [ "$(id -u)" -eq 0 ] || sudo="sudo"
        $sudo apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq python3-venv > /dev/null
        python3 -m venv .venv-test
    }
fi
.venv-test/bin/python -m pip install --quiet --disable-pip-version-check \
    -r python/requirements-test.txt ./python
MBS_TOOL="$PWD/target/debug/mbs-tool" \
    .venv-test/bin/python -m pytest -q -p no:cacheprovider python/tests
