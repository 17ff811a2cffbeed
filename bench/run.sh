#!/usr/bin/env bash
# Runs every benchmark and prints the comparison tables. Installs the peers it compares with
# (VTK, Xvfb, ...: scripts/install-deps.sh bench); build first (scripts/build.sh).
# Numbers depend on the machine: report them with the machine they came from.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh bench
build=${VOXWALL_BUILD_DIR:-build}
echo "== Google Benchmark: CPU raycaster, 1920x1080, 1/4-voxel step"
"$build/bench/voxwall_bench_raycast" --benchmark_counters_tabular=true
echo "== The main job's frames: the ray lattice (default) against a ray a pixel (--exact), PSNR against the converged render"
/usr/bin/python3 bench/lattice_bench.py --voxwall "$build/master/voxwall"
echo "== The march along the ray: steps, pre-integration, the error budget, PSNR against the converged render"
/usr/bin/python3 bench/march_bench.py --voxwall "$build/master/voxwall"
echo "== voxwall vs VTK vtkFixedPointVolumeRayCastMapper"
xvfb-run -a -s "-screen 0 3000x2000x24" /usr/bin/python3 bench/compare_vtk.py --voxwall "$build/master/voxwall" "$@"
echo "== What shading costs per codec: unshaded, six-sample gradients, cell gradients"
/usr/bin/python3 bench/shading_bench.py --voxwall "$build/master/voxwall"
echo "== Steering the bigeye wall: a command into the full frame in flight; a drag against full frames"
/usr/bin/python3 bench/interactive_bench.py --voxwall "$build/master/voxwall" --shading \
  --latency 10 --drag-seconds 20
echo "== Steering the desktop wall: the same command, and a drag with --frame-budget 100"
/usr/bin/python3 bench/interactive_bench.py --voxwall "$build/master/voxwall" --shading \
  --wall walls/desktop.json --latency 10
/usr/bin/python3 bench/interactive_bench.py --voxwall "$build/master/voxwall" --shading \
  --wall walls/desktop.json --latency 0 --drag-seconds 20 -- --frame-budget 100
echo "== Steering from the overview page in headless chromium: pointer to picture"
/usr/bin/python3 bench/interactive_bench.py --voxwall "$build/master/voxwall" --shading \
  --latency 10 --page
echo "== The wall's frame rate at the sink: a bigeye stream to 12 display pages, files, chromium pages"
/usr/bin/python3 bench/wall_fps.py --voxwall "$build/master/voxwall" \
  --replay "$build/bench/voxwall_bench_wall_replay" --chromium 4 --chromium-rate 3
echo "== Big volumes: the MRI upsampled 3x (0.95 Gvox): compress, frames vs raw, memory per rank, page cache"
/usr/bin/python3 bench/scale_bench.py --voxwall "$build/master/voxwall"
echo "== Page decode per codec on one core, and frames that meet new pages (first frame, orbits, ranks)"
/usr/bin/python3 bench/page_decode_bench.py --build "$build"
/usr/bin/python3 bench/pages_ahead_bench.py --voxwall "$build/master/voxwall" --scale 1.5
echo "== Time series: playback of new steps against raw's"
/usr/bin/python3 bench/time_series_bench.py --voxwall "$build/master/voxwall" --size 160 --steps 8 \
  --vq-rates "" --render-size 1920x1080 --codecs raw,vq,svmm,ksvd,tvq,zfp --rounds 3
if nvidia-smi -L > /dev/null 2>&1 && [ -x "$build/bench/voxwall_bench_cuda" ]; then
  echo "== CUDA against the CPU on the MRI template, raw and each codec's default file"
  work=$(mktemp -d)
  mri=/usr/share/mricron/templates/ch2better.nii.gz
  for c in vq svmm ksvd tvq; do "$build/master/voxwall" compress "$mri" --codec $c -o "$work/mri-$c.vwz"; done
  "$build/bench/voxwall_bench_cuda" --phantom 768 "$mri" "$work"/mri-*.vwz
  "$build/bench/voxwall_bench_cuda" --frames 3 --size 5760x4320 "$mri" "$work/mri-tvq.vwz"
  rm -rf "$work"
fi
