#!/usr/bin/env bash
# Prepares the GPU check (tools/gpu/run.py) on a machine with Rust: one
# folder with everything the GPU machine needs, which has no network and
# no Rust: at most 48 MiB with both builds, 32 MiB with one. Copy it there
# and run `python3 run.py --out results` in it.
#
# Usage: tools/gpu/prepare.sh OUT [--force] [--official-raft DIR] [--official-igev DIR]
#            [--binary FILE] [--autotune-binary FILE | --no-autotune]
#   OUT                    the folder to make; it must not exist (a file, a
#                          folder, a link: anything there is refused) and its
#                          parent folder must; relative to the current folder
#   --force                replace OUT, once the new one is complete, when it
#                          is a bundle this script made (it holds the marker
#                          file .mbs-gpu-bundle) and holds nothing else but
#                          what run.py unpacks beside itself (the binaries,
#                          their stamps, __pycache__); anything else at OUT,
#                          and a bundle that holds results (a results folder,
#                          a results.json or gpu_samples.csv at any depth)
#                          or any file of yours, is refused and left as it
#                          is: --force never deletes results, move them out
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
# Relative paths are taken from the folder it is run in. Every argument is
# checked before anything is built (exit 2, with a line naming the problem).
# It builds `cargo build --release -p mbs-tool --features cuda` (offline:
# no CUDA toolkit, no LLVM) and the same with `autotune` (burn picks each
# kernel by timing the candidates on the GPU), compresses each with xz -9
# (about 16 MiB), and adds run.py, official_predict.py, the PyTorch benchmarks (tools/bench),
# a test pair (testdata/middlebury-baby2), the official code and the marker
# file .mbs-gpu-bundle; then it prints the folder's size and fails when it is
# over the limit. The folder is filled under a fresh temporary name beside
# OUT (.OUT.XXXXXX, made by mktemp) and renamed to OUT when complete; on
# failure or interruption only that temporary folder is removed.
set -euo pipefail
unset CDPATH
self=$(cd "$(dirname "$0")" && pwd -P)/$(basename "$0")
root=$(cd "$(dirname "$self")/../.." && pwd -P)
caller=$PWD
marker=.mbs-gpu-bundle
marker_line="mbs GPU check bundle, made by tools/gpu/prepare.sh"
help() { sed -n '/^# Usage:/,/^#$/p' "$self" | sed -e '$d' -e 's/^# \{0,1\}//'; }
# A usage error: the problem, the usage line, exit 2.
usage() {
    echo "prepare.sh: $*" >&2
    help | sed -n '1,2p' >&2
    echo "(tools/gpu/prepare.sh --help describes each argument)" >&2
    exit 2
}
fail() { echo "prepare.sh: $*" >&2; exit 2; }
# A path as the caller meant it: relative ones from the caller's folder,
# trailing slashes dropped (OUT/ is OUT).
absolute() {
    local path=$1
    case $path in /*) ;; *) path=$caller/$path ;; esac
    while [ "${path%/}" != "$path" ] && [ "$path" != / ]; do path=${path%/}; done
    printf '%s\n' "$path"
}
# Whether $1 is a folder this script made: a real folder (not a link) with
# the marker file, whose first line is the marker's.
own_bundle() {
    [ -d "$1" ] && [ ! -L "$1" ] && [ -f "$1/$marker" ] && [ ! -L "$1/$marker" ] \
        && [ "$(head -n 1 "$1/$marker" 2>/dev/null)" = "$marker_line" ]
}
# Refuses an OUT that is there, unless --force and it is our own bundle.
check_out() {
    if [ -e "$out" ] || [ -L "$out" ]; then
        if [ "$force" = 0 ]; then
            fail "$out already exists; choose another OUT, or remove it yourself (--force replaces only a bundle prepare.sh made)"
        fi
        if [ -L "$out" ]; then
            fail "$out is a link, not a bundle prepare.sh made: --force does not replace it"
        elif [ ! -d "$out" ]; then
            fail "$out is not a folder, so not a bundle prepare.sh made: --force does not replace it"
        elif ! own_bundle "$out"; then
            fail "$out is not a bundle prepare.sh made (no $marker file in it): --force does not replace it"
        fi
        no_results "$out" "$out"
    fi
}
# Refuses bundle $1 (OUT, named $2) when it holds anything not_ours finds.
no_results() {
    local extra
    extra=$(not_ours "$1") || fail "$2 cannot be read through: --force does not replace it"
    if [ -n "$extra" ]; then
        fail "$2 holds results or files prepare.sh did not put there ($(printf '%s\n' "$extra" | listed)):" \
            "--force never deletes them; move them out of it first"
    fi
}
# Puts the previous bundle back at OUT from the temporary folder, or, when
# something took OUT meanwhile, beside it under a fresh name: never left
# in the temporary folder the exit trap removes.
restore_previous() {
    if ! mv -T "$tmp/previous" "$out"; then
        kept=$(mktemp -d "$(dirname "$out")/.$(basename "$out").previous.XXXXXX")
        mv -T "$tmp/previous" "$kept/bundle"
        echo "prepare.sh: the previous bundle is at $kept/bundle" >&2
    fi
}
# The lines read as "a, b, c, d, e, and 2 more".
listed() {
    awk 'NR <= 5 { printf "%s%s", (NR > 1 ? ", " : ""), $0 } END { if (NR > 5) printf ", and %d more", NR - 5 }'
}
# What bundle $1 holds besides what this script put there and what run.py
# unpacks beside itself, one path a line: a results.json or gpu_samples.csv
# at any depth, then any other name at its top (a results folder, a file of
# the user's).
not_ours() {
    local entry
    (cd "$1" && find . \( -name results.json -o -name gpu_samples.csv \) -print) | sed 's|^\./||'
    for entry in "$1"/* "$1"/.[!.]* "$1"/..?*; do
        [ -e "$entry" ] || [ -L "$entry" ] || continue
        case ${entry##*/} in
            "$marker"|run.py|official_predict.py|bench|data|official|vendor) ;;
            mbs-tool.xz|mbs-tool-autotune.xz|mbs-tool|mbs-tool-autotune|__pycache__) ;;
            .mbs-tool.unpacked|.mbs-tool-autotune.unpacked) ;;
            *) printf '%s\n' "${entry##*/}" ;;
        esac
    done
}

out="" force=0 raft="" igev="" binary="" tuned="" with_autotune=1
while [ $# -gt 0 ]; do
    case "$1" in
        --official-raft|--official-igev|--binary|--autotune-binary)
            [ $# -ge 2 ] && [ -n "$2" ] || usage "$1 needs a value"
            case "$1" in
                --official-raft) raft=$(absolute "$2") ;;
                --official-igev) igev=$(absolute "$2") ;;
                --binary) binary=$(absolute "$2") ;;
                --autotune-binary) tuned=$(absolute "$2") ;;
            esac
            shift 2 ;;
        --no-autotune) with_autotune=0; shift ;;
        --force) force=1; shift ;;
        -h|--help) help; exit 0 ;;
        -*) usage "unknown argument '$1'" ;;
        *)
            [ -z "$out" ] || usage "one OUT only: '$out' and '$1'"
            [ -n "$1" ] || usage "OUT is empty"
            out=$(absolute "$1"); shift ;;
    esac
done
[ -n "$out" ] || usage "OUT is missing"
[ "$out" != / ] || fail "OUT cannot be /"
parent=$(dirname "$out")
[ -d "$parent" ] || fail "$parent, the folder OUT $out would go in, does not exist"
[ -w "$parent" ] || fail "$parent, the folder OUT $out would go in, is not writable"
check_out
if [ "$with_autotune" = 0 ] && [ -n "$tuned" ]; then
    fail "--autotune-binary and --no-autotune contradict each other"
fi
check_file() {
    [ -z "$2" ] || [ -e "$2" ] || fail "$1 $2: no such file"
    [ -z "$2" ] || [ -f "$2" ] || fail "$1 $2: not a regular file"
    [ -z "$2" ] || [ -r "$2" ] || fail "$1 $2: not readable"
}
check_file --binary "$binary"
check_file --autotune-binary "$tuned"
for folder in "$raft" "$igev"; do
    if [ -n "$folder" ] && [ ! -d "$folder/core" ]; then
        fail "$folder has no core/ folder (the official code's)"
    fi
done
command -v xz >/dev/null || fail "xz is not installed (it compresses the binaries)"
if { [ -z "$binary" ] || { [ "$with_autotune" = 1 ] && [ -z "$tuned" ]; }; } && ! command -v cargo >/dev/null; then
    fail "cargo is not installed: build elsewhere and pass --binary (and --autotune-binary or --no-autotune)"
fi
[ -z "$igev" ] || command -v python3 >/dev/null || fail "python3 is needed to fetch timm for --official-igev"
limit_mib=$((with_autotune ? 48 : 32))

# Everything this script makes lies in these two temporary folders until
# the end, and only they are removed on failure or interruption. The
# partial one is beside OUT, so that the last step is a rename.
builds=$(mktemp -d)
trap 'rm -rf "$builds"' EXIT
tmp=$(mktemp -d "$parent/.$(basename "$out").XXXXXX")
trap 'rm -rf "$builds" "$tmp"' EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
cd "$root"
# Each build is copied out of target/ before the next one replaces it.
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

partial=$tmp/bundle
mkdir -p "$partial/bench" "$partial/data/pair"
echo "$marker_line" > "$partial/$marker"
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
    mkdir "$tmp/wheels"
    python3 -m pip download --quiet --no-deps --only-binary=:all: timm==0.5.4 -d "$tmp/wheels"
    python3 -m zipfile -e "$tmp/wheels"/timm-0.5.4-*.whl "$partial/vendor"
fi
size_kib=$(du -sk "$partial" | cut -f1)
if [ "$size_kib" -gt $((limit_mib * 1024)) ]; then
    echo "prepare.sh: the folder is $((size_kib / 1024)) MiB, over the ${limit_mib} MiB limit" >&2
    exit 1
fi
# OUT again, as it may have changed during the build: a bundle of ours
# without results is moved into the temporary folder (removed with it),
# anything else refused.
check_out
if [ -e "$out" ]; then
    mv -T "$out" "$tmp/previous"
    # Results made in the instant before the move go back with the bundle.
    if ! (no_results "$tmp/previous" "$out"); then
        restore_previous
        exit 2
    fi
fi
# -T: a folder made at OUT meanwhile is refused, not filled.
if ! mv -T "$partial" "$out"; then
    [ ! -e "$tmp/previous" ] || restore_previous
    echo "prepare.sh: could not rename $partial to $out" >&2
    exit 1
fi
echo "prepare.sh: $out is $((size_kib / 1024)) MiB ($size_kib KiB); on the GPU machine: cd $(basename "$out") && python3 run.py --out results"
