#!/usr/bin/env bash
# Configures and builds voxwall into build/ (Release, tuned for this machine's CPU; the CUDA
# backend when nvcc is found).
# Extra arguments go to cmake's configure step. Used by run-main.sh and test.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${VOXWALL_BUILD_DIR:-build}
jobs=${VOXWALL_JOBS:-$(nproc)}
# ccache (when installed) keeps compiled objects between builds of the same sources: a second
# build of an unchanged tree, or of a fresh clone on the same machine, recompiles nothing.
launcher=()
# Paths under the checkout count relative to it, so another clone of the same sources hits too.
export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$PWD}
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_CUDA_COMPILER_LAUNCHER=ccache)
fi
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DVOXWALL_NATIVE_ARCH=ON \
  "${launcher[@]}" "$@"
cmake --build "$build_dir" -j "$jobs"
