#!/usr/bin/env bash
# The system packages the build and the tests need, from Debian, each
# skipped when already installed (run as root, or with sudo):
# - Mesa's lavapipe, a Vulkan driver on the CPU, for the `--device vulkan`
#   tests (they fail, never skip, without one);
# - Open MPI (`mpirun`, its development files) and libclang, for the
#   `mpi` feature (data-parallel training over MPI processes: rsmpi's
#   bindgen step needs libclang) and its tests, and for the `--shard auto`
#   test under `mpirun`.
# .ci/run calls it before the lints, which build every feature;
# tools/test.sh before the tests.
set -euo pipefail
exists() { for pattern in "$@"; do compgen -G "$pattern" > /dev/null && return 0; done; return 1; }
packages=()
if ! exists '/usr/lib/*/libvulkan.so.1' '/usr/lib/libvulkan.so.1' ||
    ! exists '/usr/share/vulkan/icd.d/*.json' '/etc/vulkan/icd.d/*.json'; then
    packages+=(mesa-vulkan-drivers libvulkan1)
fi
command -v mpirun > /dev/null || packages+=(openmpi-bin)
exists '/usr/lib/*/openmpi/include/mpi.h' '/usr/include/mpi.h' || packages+=(libopenmpi-dev)
exists '/usr/lib/llvm-*/lib/libclang*.so*' '/usr/lib/*/libclang*.so*' || packages+=(libclang-dev)
if [ ${#packages[@]} -gt 0 ]; then
    sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
        "${packages[@]}" > /dev/null
fi
