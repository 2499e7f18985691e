#!/usr/bin/env bash
# The project's test command (README, .ci/run): everything a new machine
# needs, then every test of the workspace.
set -euo pipefail
cd "$(dirname "$0")/.."
# ONNX Runtime from PyPI into .ort/ (skipped when already there). The ONNX
# tests load it and fail, never skip, when it is missing.
ORT_DYLIB_PATH="$(bash tools/setup-ort.sh | tail -n 1)"
export ORT_DYLIB_PATH
cargo test --workspace --locked
