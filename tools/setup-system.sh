#!/usr/bin/env bash
# The system packages the build and the tests need, from Debian, each
# installed when the very file that the build or the tests load is missing
# (run as root, or with sudo):
# - libclang and clang's built-in headers, for the `mpi` feature: rsmpi's
#   bindgen step loads libclang (clang-sys's names: libclang.so,
#   libclang-N.so, libclang.so.N, libclang-N.so.N; never libclang-cpp,
#   which the base image's llvm brings) and parses mpi.h, which includes
#   <stddef.h> from clang's resource folder;
# - Open MPI: `mpicc` and mpi.h for the build (rsmpi probes `mpicc -show`),
#   `mpirun` for the multi-process tests and the `--shard auto` test;
# - the Vulkan loader (libvulkan.so.1) and Mesa's lavapipe ICD (a JSON
#   manifest whose library exists), for the `--device vulkan` tests;
# - Python's `venv` (ensurepip in python3's standard library, which Debian
#   ships apart), for the Python package's tests.
# The tests that use these parts fail, never skip, without them.
#
# Usage: tools/setup-system.sh [--root DIR] [--dry-run]
#   --root DIR  look for the parts under DIR, standing for the machine's
#               root (tools/tests/setup-system.sh prepares such folders)
#   --dry-run   print the packages it would install, one a line, and
#               install nothing
# .ci/run calls it before the lints, which build every feature;
# tools/test.sh before the tests.
set -euo pipefail
shopt -s nullglob

root=""
dry_run=false
while [ $# -gt 0 ]; do
    case "$1" in
        --root)
            [ $# -ge 2 ] || { echo "setup-system.sh: --root needs a folder" >&2; exit 2; }
            root="${2%/}"
            shift 2
            ;;
        --dry-run)
            dry_run=true
            shift
            ;;
        *)
            echo "setup-system.sh: unknown argument '$1' (usage: setup-system.sh [--root DIR] [--dry-run])" >&2
            exit 2
            ;;
    esac
done
if [ -n "$root" ] && ! $dry_run; then
    echo "setup-system.sh: --root is for --dry-run only (it installs into the machine's own root)" >&2
    exit 2
fi

# The first file under the root that matches one of the patterns (globs
# relative to /), as the machine would see it; fails when none does.
first_match() {
    local pattern path
    for pattern in "$@"; do
        for path in $root$pattern; do
            [ -e "$path" ] && return 0
        done
    done
    return 1
}

# libclang as clang-sys 1.9 (bindgen's loader) looks for it: its folders
# and its four file names, less libclang-cpp, a different library.
has_libclang() {
    local folder name
    for folder in $root/usr/local/llvm*/lib* $root/usr/local/lib* $root/usr/local/lib*/* \
        $root/usr/local/lib*/*/* $root/usr/lib* $root/usr/lib*/* $root/usr/lib*/*/*; do
        [ -d "$folder" ] || continue
        for name in "$folder"/libclang.so "$folder"/libclang-*.so "$folder"/libclang.so.* \
            "$folder"/libclang-*.so.*; do
            case "${name##*/}" in *-cpp.*) continue ;; esac
            [ -e "$name" ] && return 0
        done
    done
    return 1
}

# A program on the PATH, under the root.
has_program() {
    local folder
    IFS=: read -ra folders <<< "$PATH"
    for folder in "${folders[@]}"; do
        [ -n "$folder" ] && [ -x "$root$folder/$1" ] && [ ! -d "$root$folder/$1" ] && return 0
    done
    return 1
}

# A lavapipe ICD manifest whose library exists (an absolute path, or a bare
# name the loader finds in the library folders).
has_lavapipe_icd() {
    local manifest library
    for manifest in $root/usr/share/vulkan/icd.d/lvp_icd*.json \
        $root/etc/vulkan/icd.d/lvp_icd*.json $root/usr/local/share/vulkan/icd.d/lvp_icd*.json; do
        library=$(sed -n 's/.*"library_path"[[:space:]]*:[[:space:]]*"\([^"]*\)".*/\1/p' "$manifest" | head -n 1)
        [ -n "$library" ] || continue
        case "$library" in
            /*) [ -e "$root$library" ] && return 0 ;;
            *) first_match "/usr/lib/*/$library" "/usr/lib/$library" "/usr/local/lib/$library" && return 0 ;;
        esac
    done
    return 1
}

# ensurepip in the standard library of the python3 on the PATH (Debian
# moves it into python3.X-venv); python3 itself from the PATH, under the
# root.
has_python_venv() {
    local stdlib
    has_program python3 || return 1
    stdlib=$(python3 -c 'import sysconfig; print(sysconfig.get_path("stdlib"))') || return 1
    [ -e "$root$stdlib/ensurepip/__init__.py" ]
}

packages=()
need() { local package; for package in "$@"; do [[ " ${packages[*]-} " == *" $package "* ]] || packages+=("$package"); done; }

has_libclang || need libclang-dev
first_match '/usr/lib/llvm-*/lib/clang/*/include/stddef.h' '/usr/lib/clang/*/include/stddef.h' \
    '/usr/local/lib/clang/*/include/stddef.h' || need libclang-dev
has_program mpicc || need libopenmpi-dev
first_match '/usr/lib/*/openmpi/include/mpi.h' '/usr/include/mpi.h' '/usr/local/include/mpi.h' || need libopenmpi-dev
has_program mpirun || need openmpi-bin
first_match '/usr/lib/*/libvulkan.so.1' '/usr/lib/libvulkan.so.1' '/usr/local/lib/libvulkan.so.1' || need libvulkan1
has_lavapipe_icd || need mesa-vulkan-drivers
if ! has_program python3; then
    need python3 python3-venv
elif ! has_python_venv; then
    need python3-venv
fi

if $dry_run; then
    [ ${#packages[@]} -eq 0 ] || printf '%s\n' "${packages[@]}"
    exit 0
fi
if [ ${#packages[@]} -gt 0 ]; then
    echo "setup-system.sh: installing ${packages[*]}" >&2
    sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
        "${packages[@]}" > /dev/null
fi
