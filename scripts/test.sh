#!/usr/bin/env bash
# Installs what voxwall needs, checks formatting, builds everything (with the CUDA backend when
# nvcc is present: its tests skip without a GPU), runs the whole test suite, builds and runs it
# again under AddressSanitizer + UndefinedBehaviorSanitizer (all but the multi-rank scenarios
# and browser tests, which run in the release pass; five scenarios run in both), then runs each
# libFuzzer target for a short while (clang build).
set -euo pipefail
cd "$(dirname "$0")/.."
started=$(date +%s)
stage() { echo "== $* (at $(($(date +%s) - started)) s)"; }
bash scripts/install-deps.sh test

stage "formatting (clang-format --dry-run)"
git ls-files '*.cpp' '*.hpp' '*.cu' '*.inl' | xargs clang-format --dry-run --Werror

stage "release build and tests"
cuda=()
if command -v nvidia-smi > /dev/null && nvidia-smi -L > /dev/null 2>&1; then
  cuda=(-DCMAKE_CUDA_ARCHITECTURES=native)  # the CUDA tests run on this machine's GPU
else
  # No GPU to run the kernels: nvcc still compiles all of them (front end, templates, lowering to
  # PTX for one architecture) to prove they build, without the machine code for two architectures
  # and with NVVM's optimizer at -O1 instead of -O3: the heaviest unit (ksvd's 4^3 blocks) takes
  # 14 s instead of 108 s on this VM, and nothing compiled here runs.
  cuda=(-DCMAKE_CUDA_ARCHITECTURES=80-virtual "-DCMAKE_CUDA_FLAGS=-Xcicc -O1")
fi
bash scripts/build.sh -DBUILD_TESTING=ON -DVOXWALL_BUILD_BENCH=ON "${cuda[@]}"
ctest --test-dir build --output-on-failure -j "$(nproc)"

stage "sanitizer build and tests (ASan + UBSan, CPU only, portable: every SIMD target)"
# Without -march=native the packets are compiled for AVX2 and AVX-512 and picked at run time, as in
# a binary that moves between machines; Packets.EverySimdTargetGivesTheSamePicture runs each.
# -O1 -g1 (the sanitizers' usual level; line tables are all their reports need) compile in half
# the time of -O2 -g.
VOXWALL_BUILD_DIR=build-asan bash scripts/build.sh -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
  -DVOXWALL_SANITIZE=ON -DVOXWALL_CUDA=OFF -DVOXWALL_BUILD_BENCH=OFF -DVOXWALL_NATIVE_ARCH=OFF
# Every test runs once: LeakSanitizer's tracer no longer crashes at a passing test's exit (it
# scanned a thread's dynamic TLS after glibc had moved it; the sanitizer build now loads
# OpenImageIO with the program, core/CMakeLists.txt says why).
asan_env=(ASAN_OPTIONS=detect_leaks=1 "LSAN_OPTIONS=suppressions=$PWD/tests/lsan.supp"
          UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1)
env "${asan_env[@]}" ctest --test-dir build-asan --output-on-failure -j "$(nproc)" \
  -LE '^(mpi|browser)$'

stage "fuzz targets (clang, libFuzzer, 20 s each)"
launcher=()
command -v ccache > /dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
CCACHE_BASEDIR=$PWD cmake -S . -B build-fuzz -G Ninja -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
  -DVOXWALL_BUILD_FUZZERS=ON -DVOXWALL_CUDA=OFF \
  -DVOXWALL_BUILD_BENCH=OFF -DVOXWALL_SIMD_DISPATCH=OFF "${launcher[@]}"
CCACHE_BASEDIR=$PWD cmake --build build-fuzz -j "$(nproc)" --target vwz_reader_fuzz vwz_make_seeds frame_messages_fuzz wire_fuzz make_wire_seeds \
  sink_fuzz make_sink_seeds config_files_fuzz make_config_seeds dicom_reader_fuzz make_dicom_seeds
ASAN_OPTIONS=detect_leaks=1 LSAN_OPTIONS=suppressions=$PWD/tests/lsan.supp \
  ctest --test-dir build-fuzz --output-on-failure -L fuzz -j "$(nproc)"
stage "done"
