#!/usr/bin/env bash
# Installs what voxwall needs, checks formatting, builds everything (with the CUDA backend when
# nvcc is present: its tests skip without a GPU), runs the whole test suite, builds and runs it
# again under AddressSanitizer + UndefinedBehaviorSanitizer, then runs each libFuzzer target for a
# short while (clang build).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh test

echo "== formatting (clang-format --dry-run)"
git ls-files '*.cpp' '*.hpp' '*.cu' '*.inl' | xargs clang-format --dry-run --Werror

echo "== release build and tests"
bash scripts/build.sh -DBUILD_TESTING=ON -DVOXWALL_BUILD_BENCH=ON
ctest --test-dir build --output-on-failure -j "$(nproc)"

echo "== sanitizer build and tests (ASan + UBSan, CPU only, portable: every SIMD target)"
# Without -march=native the packets are compiled for AVX2 and AVX-512 and picked at run time, as in
# a binary that moves between machines; Packets.EverySimdTargetGivesTheSamePicture runs each.
VOXWALL_BUILD_DIR=build-asan bash scripts/build.sh -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DVOXWALL_SANITIZE=ON -DVOXWALL_CUDA=OFF -DVOXWALL_BUILD_BENCH=OFF -DVOXWALL_NATIVE_ARCH=OFF
ASAN_OPTIONS=detect_leaks=1 LSAN_OPTIONS=suppressions=$PWD/tests/lsan.supp \
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-asan --output-on-failure -j "$(nproc)"

echo "== fuzz targets (clang, libFuzzer, 20 s each)"
launcher=()
command -v ccache > /dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
CCACHE_BASEDIR=$PWD cmake -S . -B build-fuzz -G Ninja -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DVOXWALL_BUILD_FUZZERS=ON -DVOXWALL_CUDA=OFF \
  -DVOXWALL_BUILD_BENCH=OFF -DVOXWALL_SIMD_DISPATCH=OFF "${launcher[@]}"
CCACHE_BASEDIR=$PWD cmake --build build-fuzz -j "$(nproc)" --target vwz_reader_fuzz vwz_make_seeds frame_messages_fuzz wire_fuzz make_wire_seeds \
  sink_fuzz make_sink_seeds config_files_fuzz make_config_seeds dicom_reader_fuzz make_dicom_seeds
ASAN_OPTIONS=detect_leaks=1 LSAN_OPTIONS=suppressions=$PWD/tests/lsan.supp \
  ctest --test-dir build-fuzz --output-on-failure -L fuzz
