#!/usr/bin/env bash
# Configures and builds voxwall into build/ (Release, tuned for this machine's CPU; the CUDA
# backend when nvcc is found).
# Extra arguments go to cmake's configure step. Used by run-main.sh and test.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${VOXWALL_BUILD_DIR:-build}
jobs=${VOXWALL_JOBS:-$(nproc)}
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DVOXWALL_NATIVE_ARCH=ON "$@"
cmake --build "$build_dir" -j "$jobs"
