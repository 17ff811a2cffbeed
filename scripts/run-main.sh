#!/usr/bin/env bash
# The main job on the built-in default data: installs what voxwall needs, builds it, compresses
# the MRI template from Debian's mricron-data (or a generated Shepp-Logan phantom when that is
# not installed) into a .vwz file, shows what is in it, starts the display-wall sink for the
# bigeye wall (3x4 full-HD displays) on loopback, and renders an orbit of the volume on
# ${VOXWALL_RANKS:-2} MPI ranks straight onto the wall: every rank JPEG-compresses its part of
# the screen and streams it to the sink, which writes each display's picture (and a mosaic of the
# whole wall) to out/wall/ only when every display pixel of a frame has arrived.
# While it runs, the wall is also in browsers: the sink serves the overview page (watch, see the
# balancer's rectangles, steer the camera) and one page per display (for a kiosk browser on each
# display's host: /displays lists them with launch lines) on loopback, and the script prints the
# addresses.
#   VOXWALL_WALL=walls/ci-2x2.json   another wall (a voxwall wall file or a Tide configuration)
#   VOXWALL_FRAMES=6 VOXWALL_RANKS=2 frames and ranks
#   VOXWALL_HTTP=127.0.0.1:8080      where the pages are served (default: a free loopback port)
#   VOXWALL_CUDA=ON|OFF              build the CUDA backend (default: only where nvidia-smi finds a
#                                    GPU, since the main job renders on the CPU otherwise)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh main
# The product only: tests and benchmarks need more packages (install-deps.sh test / bench). The
# CUDA backend takes most of a cold build and cannot run without a GPU: built only where one is.
cuda=${VOXWALL_CUDA:-$(nvidia-smi -L > /dev/null 2>&1 && echo ON || echo OFF)}
bash scripts/build.sh -DBUILD_TESTING=OFF -DVOXWALL_BUILD_BENCH=OFF -DVOXWALL_CUDA="$cuda"
voxwall=build/master/voxwall
mri=/usr/share/mricron/templates/ch2better.nii.gz
if [ -f "$mri" ]; then input=$mri; else input=generated:shepp-logan:256; fi
wall=${VOXWALL_WALL:-walls/bigeye.json}
frames=${VOXWALL_FRAMES:-6}
mkdir -p out
"$voxwall" compress "$input" -o out/default.vwz
"$voxwall" info out/default.vwz

rm -rf out/wall
"$voxwall" sink --wall "$wall" --listen 127.0.0.1:0 --out out/wall --mosaic --frames "$frames" \
  --http "${VOXWALL_HTTP:-127.0.0.1:0}" --no-stdin > out/sink.log 2>&1 &
sink=$!
trap 'kill "$sink" 2>/dev/null || true' EXIT
port=
for _ in $(seq 200); do
  port=$(sed -n 's/.*listening on 127.0.0.1:\([0-9]*\).*/\1/p' out/sink.log)
  [ -n "$port" ] && break
  sleep 0.05
done
[ -n "$port" ] || { cat out/sink.log; echo "the sink did not start" >&2; exit 1; }
head -1 out/sink.log
page=$(sed -n 's/.*wall page at \(http[^ ]*\).*/\1/p' out/sink.log)
if [ -n "$page" ]; then
  http_port=${page##*:}
  http_port=${http_port%/}
  echo "the wall in a browser while the job runs: $page (from another machine:" \
    "ssh -L $http_port:127.0.0.1:$http_port $(hostname), then open that address)"
  echo "one page per display, each for a kiosk browser on that display's host:" \
    "${page}displays lists them with their launch lines"
fi

mpirun=(mpirun --oversubscribe --bind-to none -np "${VOXWALL_RANKS:-2}")
[ "$(id -u)" = 0 ] && mpirun+=(--allow-run-as-root)
"${mpirun[@]}" "$voxwall" render out/default.vwz --wall "$wall" --sink "127.0.0.1:$port" \
  --frames "$frames" --shading
wait "$sink"
trap - EXIT
tail -n +2 out/sink.log
echo "per-display images (and the whole wall as frame_*_mosaic.png) in $(pwd)/out/wall"
