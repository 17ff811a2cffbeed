#!/usr/bin/env bash
# The main job on the built-in default data: installs what voxwall needs, builds it, compresses
# the MRI template from Debian's mricron-data (or a generated Shepp-Logan phantom when that is
# not installed) into a .vwz file, shows what is in it, and renders an orbit of it on
# ${VOXWALL_RANKS:-2} MPI ranks (rank 0 cuts the screen among them every frame from the costs it
# measured) to PNG files in out/frames/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
voxwall=build/master/voxwall
mri=/usr/share/mricron/templates/ch2better.nii.gz
if [ -f "$mri" ]; then input=$mri; else input=generated:shepp-logan:256; fi
mkdir -p out
"$voxwall" compress "$input" -o out/default.vwz
"$voxwall" info out/default.vwz
mpirun=(mpirun --oversubscribe --bind-to none -np "${VOXWALL_RANKS:-2}")
[ "$(id -u)" = 0 ] && mpirun+=(--allow-run-as-root)
"${mpirun[@]}" "$voxwall" render out/default.vwz --size "${VOXWALL_SIZE:-1280x720}" \
  --frames "${VOXWALL_FRAMES:-12}" --shading --out out/frames
echo "frames written to $(pwd)/out/frames"
