#!/usr/bin/env bash
# Tests tools/setup-system.sh's detection: for folders standing for a
# machine's root (a fresh base image, a complete machine, and a complete
# machine less one part at a time), `--root DIR --dry-run` must print
# exactly the Debian packages that machine lacks. The fresh image has
# llvm's libclang-cpp and no libclang: the case a glob on libclang* missed.
set -euo pipefail
cd "$(dirname "$0")/../.."
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0

python=$(command -v python3)
stdlib=$(python3 -c 'import sysconfig; print(sysconfig.get_path("stdlib"))')

# Files of a machine, relative to its root, by the part they belong to.
put() { local root=$1 file; shift; for file in "$@"; do mkdir -p "$root$(dirname "$file")"; : > "$root$file"; done; }
base_image() {
    put "$1" /usr/lib/llvm-14/lib/libclang-cpp.so.14 /usr/lib/x86_64-linux-gnu/libclang-cpp.so.14 \
        /usr/lib/llvm-14/lib/libLLVM-14.so
    put "$1" "$python" "$stdlib/ensurepip/__init__.py"
    chmod +x "$1$python"
}
libclang() { put "$1" /usr/lib/x86_64-linux-gnu/libclang-14.so.14 /usr/lib/llvm-14/lib/libclang.so.1; }
clang_headers() { put "$1" /usr/lib/llvm-14/lib/clang/14.0.6/include/stddef.h; }
mpicc() { put "$1" /usr/bin/mpicc; chmod +x "$1/usr/bin/mpicc"; }
mpi_header() { put "$1" /usr/lib/x86_64-linux-gnu/openmpi/include/mpi.h; }
mpirun() { put "$1" /usr/bin/mpirun; chmod +x "$1/usr/bin/mpirun"; }
vulkan_loader() { put "$1" /usr/lib/x86_64-linux-gnu/libvulkan.so.1; }
lavapipe() {
    put "$1" /usr/lib/x86_64-linux-gnu/libvulkan_lvp.so
    mkdir -p "$1/usr/share/vulkan/icd.d"
    printf '{\n    "ICD": {\n        "api_version": "1.3.230",\n        "library_path": "/usr/lib/x86_64-linux-gnu/libvulkan_lvp.so"\n    },\n    "file_format_version": "1.0.0"\n}\n' \
        > "$1/usr/share/vulkan/icd.d/lvp_icd.x86_64.json"
}
parts=(libclang clang_headers mpicc mpi_header mpirun vulkan_loader lavapipe)
complete_machine() { local part; base_image "$1"; for part in "${parts[@]}"; do "$part" "$1"; done; }

# Runs the detection on a root and compares the packages, in any order.
expect() {
    local case=$1 root=$2 expected actual; shift 2
    expected=$(printf '%s\n' "$@" | sed '/^$/d' | sort)
    actual=$(bash tools/setup-system.sh --root "$root" --dry-run | sort)
    if [ "$expected" == "$actual" ]; then
        echo "ok: $case"
    else
        echo "FAILED: $case: expected [$(echo $expected)], got [$(echo $actual)]"
        failures=$((failures + 1))
    fi
}

root="$work/fresh"; base_image "$root"
expect "a fresh base image (llvm's libclang-cpp, no libclang)" "$root" \
    libclang-dev libopenmpi-dev openmpi-bin libvulkan1 mesa-vulkan-drivers

root="$work/complete"; complete_machine "$root"
expect "a complete machine" "$root"

declare -A package_of=(
    [libclang]=libclang-dev [clang_headers]=libclang-dev [mpicc]=libopenmpi-dev
    [mpi_header]=libopenmpi-dev [mpirun]=openmpi-bin [vulkan_loader]=libvulkan1
    [lavapipe]=mesa-vulkan-drivers
)
for missing in "${parts[@]}"; do
    root="$work/without-$missing"; base_image "$root"
    for part in "${parts[@]}"; do [ "$part" == "$missing" ] || "$part" "$root"; done
    expect "a complete machine without $missing" "$root" "${package_of[$missing]}"
done

root="$work/without-venv"; complete_machine "$root"; rm "$root$stdlib/ensurepip/__init__.py"
expect "a complete machine without Python's ensurepip" "$root" python3-venv

root="$work/without-python"; complete_machine "$root"; rm "$root$python"
expect "a complete machine without python3" "$root" python3 python3-venv

root="$work/lavapipe-library-gone"; complete_machine "$root"
rm "$root/usr/lib/x86_64-linux-gnu/libvulkan_lvp.so"
expect "a lavapipe manifest whose library is gone" "$root" mesa-vulkan-drivers

root="$work/other-icd"; complete_machine "$root"; rm "$root"/usr/share/vulkan/icd.d/lvp_icd*.json
printf '{"ICD": {"library_path": "libGLX_nvidia.so.0"}}\n' > "$root/usr/share/vulkan/icd.d/nvidia_icd.json"
expect "another vendor's ICD in place of lavapipe" "$root" mesa-vulkan-drivers

root="$work/libclang-symlink-only"; complete_machine "$root"
rm "$root/usr/lib/x86_64-linux-gnu/libclang-14.so.14" "$root/usr/lib/llvm-14/lib/libclang.so.1"
put "$root" /usr/lib/llvm-14/lib/libclang.so
expect "libclang as libclang-dev's unversioned name" "$root"

root="$work/mpicc-a-folder"; complete_machine "$root"; rm "$root/usr/bin/mpicc"; mkdir "$root/usr/bin/mpicc"
expect "a folder named mpicc" "$root" libopenmpi-dev

if bash tools/setup-system.sh --root "$work/fresh" > /dev/null 2>&1; then
    echo "FAILED: --root without --dry-run was accepted"; failures=$((failures + 1))
else
    echo "ok: --root without --dry-run is refused"
fi

[ "$failures" -eq 0 ] || { echo "$failures setup-system case(s) failed"; exit 1; }
