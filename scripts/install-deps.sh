#!/usr/bin/env bash
# Installs the Debian 12 packages voxwall needs, by purpose:
#   install-deps.sh main    build the product and run the main job (scripts/run-main.sh)
#   install-deps.sh test    main + tests, fuzzing and formatting (scripts/test.sh, CI) [default]
#   install-deps.sh bench   test + the benchmark peers and plots (bench/run.sh and friends)
# Run as root (or with sudo). docs/platform.md says how CMake finds each library.
set -euo pipefail

purpose=${1:-test}
main=(
  build-essential cmake ninja-build pkg-config git procps ccache
  libopenmpi-dev openmpi-bin
  libglm-dev libeigen3-dev
  libturbojpeg0-dev
  libopenimageio-dev
  libcli11-dev nlohmann-json3-dev libxxhash-dev libpugixml-dev
  libnifti2-dev libteem-dev zlib1g-dev libbz2-dev
  # the zfp codec
  libzfp-dev
  # DICOM series
  libgdcm-dev
  libasio-dev
  # the sink's web page: Boost.Beast (header-only)
  libboost-dev
  # the CPU raycaster's SIMD ray packets, with runtime dispatch
  libhwy-dev
  # real data: the MRI template used as the default volume
  mricron-data
)
test=(
  clang-format
  libgtest-dev libgmock-dev libbenchmark-dev
  # fuzzing: clang's libFuzzer
  clang libclang-rt-14-dev
  # a real 4D NIfTI (fMRI) among nibabel's test files, for the time series tests
  python3-nibabel
  # the browser test of the sink's web page (tests/web)
  chromium chromium-driver python3-selenium
)
bench=(
  libjpeg-turbo-progs time
  python3-numpy python3-matplotlib python3-pil python3-vtk9 xvfb xauth zfp astcenc
)
case $purpose in
  main) packages=("${main[@]}") ;;
  test) packages=("${main[@]}" "${test[@]}") ;;
  bench) packages=("${main[@]}" "${test[@]}" "${bench[@]}") ;;
  *) echo "usage: install-deps.sh [main|test|bench]" >&2; exit 2 ;;
esac

if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; else SUDO=; fi
export DEBIAN_FRONTEND=noninteractive
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "install-deps ($purpose): installing ${#missing[@]} packages: ${missing[*]}"
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
else
  echo "install-deps ($purpose): all ${#packages[@]} packages present"
fi
