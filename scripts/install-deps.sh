#!/usr/bin/env bash
# Installs every Debian 12 package voxwall needs to build, test and benchmark.
# Shared by the README's two commands and .ci/run. Run as root (or with sudo).
set -euo pipefail

packages=(
  # build
  build-essential cmake ninja-build pkg-config git clang-format
  # libraries (docs/platform.md says how CMake finds each)
  libopenmpi-dev openmpi-bin procps
  libglm-dev
  libturbojpeg0-dev libjpeg-turbo-progs
  libopenimageio-dev
  libcli11-dev nlohmann-json3-dev libxxhash-dev
  libnifti2-dev libteem-dev zlib1g-dev libbz2-dev
  libasio-dev
  # tests, fuzzing (clang's libFuzzer) and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev clang libclang-rt-14-dev
  # real data: the MRI template used as the default volume
  mricron-data
  # benchmark peers and plots
  python3-numpy python3-matplotlib python3-vtk9 xvfb xauth zfp libzfp-dev astcenc
)

if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; else SUDO=; fi
export DEBIAN_FRONTEND=noninteractive
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "install-deps: installing ${#missing[@]} packages: ${missing[*]}"
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
else
  echo "install-deps: all ${#packages[@]} packages present"
fi
