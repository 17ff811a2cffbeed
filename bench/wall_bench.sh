#!/usr/bin/env bash
# The wall benchmark: JPEG tile compression of one 5772x4338 bigeye frame (the MRI, rendered by
# voxwall) against libjpeg-turbo's own tjbench on the same pixels, bytes per frame against raw
# RGB, and end-to-end frame rate and latency (camera decided on rank 0 -> frame presented by the
# sink) for 1, 2 and 4 ranks on loopback.
#   bash bench/wall_bench.sh [--quality Q] [--subsampling 420] [--ranks "1 2 4"] [--frames N]
set -euo pipefail
cd "$(dirname "$0")/.."
quality=90 sub=420 ranks="1 2 4" frames=5
while [ $# -gt 0 ]; do
  case $1 in
    --quality) quality=$2; shift 2 ;;
    --subsampling) sub=$2; shift 2 ;;
    --ranks) ranks=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    *) echo "usage: $0 [--quality Q] [--subsampling S] [--ranks LIST] [--frames N]" >&2; exit 2 ;;
  esac
done
voxwall=${VOXWALL:-build/master/voxwall}
tiles=${VOXWALL_BENCH_TILES:-build/bench/voxwall_bench_tiles}
[ -x "$voxwall" ] && [ -x "$tiles" ] || { echo "build first: bash scripts/build.sh" >&2; exit 1; }
command -v tjbench > /dev/null || { echo "needs tjbench (Debian's libjpeg-turbo-progs)" >&2; exit 1; }
work=$(mktemp -d "${TMPDIR:-/tmp}/voxwall-wall-bench.XXXXXX")
trap 'rm -rf "$work"' EXIT
mri=/usr/share/mricron/templates/ch2better.nii.gz
"$voxwall" compress "$mri" -o "$work/mri.vwz" -q > /dev/null
mpi=(mpirun --oversubscribe --bind-to none)
[ "$(id -u)" = 0 ] && mpi+=(--allow-run-as-root)

echo "machine: $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')), $(date -u +%F)"
echo
echo "## Frame codec on one bigeye frame (MRI, shaded)"
echo
"$voxwall" render "$work/mri.vwz" --wall walls/bigeye.json --shading --exact --out "$work/frame" -q
"$tiles" "$work/frame/frame_00000.png" "$work/frame.ppm" "$quality" "$sub" 3
echo
echo "libjpeg-turbo's tjbench on the same frame (one thread, RGB input, fast DCT, q$quality $sub):"
tjbench "$work/frame.ppm" "$quality" -rgb -subsamp "$sub" -fastdct -componly -nowrite -quiet \
  -benchtime 3 -warmup 1 | sed -n '/^[A-Z]/p'

echo
echo "## End to end on loopback (desktop wall 1920x1080, MRI, shaded, orbit, $frames frames)"
echo
echo "| ranks | render frames/s | sink frames presented | mean latency ms (camera decided -> presented) | bytes/frame |"
echo "|---|---|---|---|---|"
for n in $ranks; do
  "$voxwall" sink --wall walls/desktop.json --listen 127.0.0.1:0 --frames "$frames" --no-stdin \
    > "$work/sink.log" 2>&1 &
  sink=$!
  port=
  for _ in $(seq 200); do
    port=$(sed -n 's/.*listening on 127.0.0.1:\([0-9]*\).*/\1/p' "$work/sink.log")
    [ -n "$port" ] && break
    sleep 0.05
  done
  out=$("${mpi[@]}" -np "$n" "$voxwall" render "$work/mri.vwz" --wall walls/desktop.json \
    --sink "127.0.0.1:$port" --frames "$frames" --orbit-deg 5 --shading --exact \
    --jpeg-quality "$quality" --subsampling "$sub" 2>/dev/null)
  wait "$sink" || true
  fps=$(echo "$out" | sed -n 's/.* \([0-9.]*\) frames\/s.*/\1/p')
  summary=$(tail -1 "$work/sink.log")
  presented=$(echo "$summary" | sed -n 's/^sink: \([0-9]*\) frame.*/\1/p')
  latency=$(echo "$summary" | sed -n 's/.*mean latency \([0-9.]*\) ms.*/\1/p')
  kib=$(grep -m1 ' presented:' "$work/sink.log" | sed -n 's/.*rank(s), \([0-9.]*\) KiB.*/\1/p')
  note=""; [ "$n" -gt "$(nproc)" ] && note=" (oversubscribed)"
  echo "| $n$note | $fps | $presented/$frames | $latency | ${kib} KiB |"
done
