#!/usr/bin/env bash
# Prepares the GPU check (tools/gpu/run.py) on a machine with Rust: one
# folder with everything the GPU machine needs, which has no network and
# no Rust: at most 48 MiB with both builds, 32 MiB with one. Copy it there
# and run `python3 run.py --out results` in it.
#
# Usage: tools/gpu/prepare.sh OUT [--official-raft DIR] [--official-igev DIR]
#            [--binary FILE] [--autotune-binary FILE | --no-autotune]
#   OUT                    the folder to fill (made anew)
#   --official-raft DIR    a clone of princeton-vl/RAFT-Stereo: its core/ is
#                          copied (never committed here), for the official
#                          step and predictions
#   --official-igev DIR    the IGEV-Stereo folder of a clone of gangweiX/IGEV;
#                          timm 0.5.4, which it needs, comes from PyPI
#   --binary FILE          an mbs-tool built with --features cuda already,
#                          instead of building one (about 30 minutes on 2 cores)
#   --autotune-binary FILE one built with --features cuda,autotune already
#   --no-autotune          leave the autotune build out (run.py skips its phase)
#
# It builds `cargo build --release -p mbs-tool --features cuda` (offline:
# no CUDA toolkit, no LLVM) and the same with `autotune` (burn picks each
# kernel by timing the candidates on the GPU), compresses each with xz -9
# (about 16 MiB), and adds run.py, official_predict.py, the PyTorch benchmarks (tools/bench),
# a test pair (testdata/middlebury-baby2) and the official code; then it
# prints the folder's size and fails when it is over the limit.
set -euo pipefail
cd "$(dirname "$0")/../.."
usage() { sed -n '7,18p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
[ $# -ge 1 ] || usage
out=$1
shift
raft="" igev="" binary="" tuned="" with_autotune=1
while [ $# -gt 0 ]; do
    case "$1" in
        --official-raft) raft=${2:?--official-raft needs a folder}; shift 2 ;;
        --official-igev) igev=${2:?--official-igev needs a folder}; shift 2 ;;
        --binary) binary=${2:?--binary needs a file}; shift 2 ;;
        --autotune-binary) tuned=${2:?--autotune-binary needs a file}; shift 2 ;;
        --no-autotune) with_autotune=0; shift ;;
        *) echo "prepare.sh: unknown argument '$1'" >&2; usage ;;
    esac
done
if [ "$with_autotune" = 0 ] && [ -n "$tuned" ]; then
    echo "prepare.sh: --autotune-binary and --no-autotune contradict each other" >&2
    exit 2
fi
limit_mib=$((with_autotune ? 48 : 32))
for folder in "$raft" "$igev"; do
    if [ -n "$folder" ] && [ ! -d "$folder/core" ]; then
        echo "prepare.sh: $folder has no core/ folder (the official code's)" >&2
        exit 1
    fi
done
# Each build is copied out of target/ before the next one replaces it.
builds=$(mktemp -d)
trap 'rm -rf "$builds"' EXIT
if [ -z "$binary" ]; then
    cargo build --release --locked -p mbs-tool --features cuda
    binary=$builds/mbs-tool
    cp target/release/mbs-tool "$binary"
fi
if [ "$with_autotune" = 1 ] && [ -z "$tuned" ]; then
    cargo build --release --locked -p mbs-tool --features cuda,autotune
    tuned=$builds/mbs-tool-autotune
    cp target/release/mbs-tool "$tuned"
fi
[ -f "$binary" ] || { echo "prepare.sh: --binary $binary: no such file" >&2; exit 1; }
[ -z "$tuned" ] || [ -f "$tuned" ] || { echo "prepare.sh: --autotune-binary $tuned: no such file" >&2; exit 1; }

# Made under a temporary name and renamed when complete.
partial="$out.partial"
rm -rf "$partial"
mkdir -p "$partial/bench" "$partial/data/pair"
echo "prepare.sh: compressing $binary ($(du -m "$binary" | cut -f1) MiB) with xz -9" >&2
xz -9 -T0 -c "$binary" > "$partial/mbs-tool.xz"
if [ -n "$tuned" ]; then
    echo "prepare.sh: compressing $tuned ($(du -m "$tuned" | cut -f1) MiB) with xz -9" >&2
    xz -9 -T0 -c "$tuned" > "$partial/mbs-tool-autotune.xz"
fi
cp tools/gpu/run.py tools/gpu/official_predict.py "$partial/"
cp tools/bench/official_step_vs_torch.py tools/bench/s3_torch.py tools/bench/train_step_vs_torch.py "$partial/bench/"
cp testdata/middlebury-baby2/view1.png testdata/middlebury-baby2/view2.png "$partial/data/pair/"
if [ -n "$raft" ]; then
    mkdir -p "$partial/official/RAFT-Stereo"
    (cd "$raft" && find core -name '*.py' -print0 | xargs -0 tar -cf -) | tar -xf - -C "$partial/official/RAFT-Stereo"
fi
if [ -n "$igev" ]; then
    mkdir -p "$partial/official/IGEV-Stereo" "$partial/vendor"
    (cd "$igev" && find core -name '*.py' -print0 | xargs -0 tar -cf -) | tar -xf - -C "$partial/official/IGEV-Stereo"
    # timm 0.5.4 is pure Python: its wheel unpacked is importable (run.py
    # puts vendor/ on PYTHONPATH for the official step).
    wheels=$(mktemp -d)
    python3 -m pip download --quiet --no-deps --only-binary=:all: timm==0.5.4 -d "$wheels"
    python3 -m zipfile -e "$wheels"/timm-0.5.4-*.whl "$partial/vendor"
    rm -rf "$wheels"
fi
size_kib=$(du -sk "$partial" | cut -f1)
if [ "$size_kib" -gt $((limit_mib * 1024)) ]; then
    echo "prepare.sh: the folder is $((size_kib / 1024)) MiB, over the ${limit_mib} MiB limit" >&2
    rm -rf "$partial"
    exit 1
fi
rm -rf "$out"
mv "$partial" "$out"
echo "prepare.sh: $out is $((size_kib / 1024)) MiB ($size_kib KiB); on the GPU machine: cd $(basename "$out") && python3 run.py --out results"
