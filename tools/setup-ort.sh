#!/usr/bin/env bash
# Installs ONNX Runtime 1.31.1 from PyPI into the project's .ort/ folder,
# where mbs finds it (see `mbs_infer::onnx::runtime`). Idempotent: does
# nothing when the library is already there.
#
#   tools/setup-ort.sh          CPU runtime (package onnxruntime)
#   tools/setup-ort.sh --gpu    CUDA runtime (package onnxruntime-gpu; CUDA 13, cuDNN 9)
#
# Prints the library's path on its last line.
set -euo pipefail
cd "$(dirname "$0")/.."

VERSION=1.31.1
PACKAGE=onnxruntime
TARGET=.ort
CAPI="$TARGET/onnxruntime/capi"
LIB="$CAPI/libonnxruntime.so.$VERSION"
MARKER="$LIB"
case "${1:-}" in
    "") ;;
    --gpu) PACKAGE=onnxruntime-gpu; MARKER="$CAPI/libonnxruntime_providers_cuda.so" ;;
    *) echo "usage: $0 [--gpu]" >&2; exit 2 ;;
esac

if [[ ! -f "$MARKER" ]]; then
    # --upgrade: the GPU package replaces a CPU one installed before.
    python3 -m pip install --quiet --disable-pip-version-check --no-deps \
        --upgrade --target "$TARGET" "$PACKAGE==$VERSION"
fi
if [[ ! -f "$MARKER" ]]; then
    echo "error: $PACKAGE $VERSION installed into $TARGET but $MARKER is missing" >&2
    exit 1
fi
echo "$PWD/$LIB"
