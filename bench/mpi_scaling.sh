#!/usr/bin/env bash
# Distributed rendering benchmark: frames per second, imbalance and where rank 0's frame time
# goes, for several rank counts and screen sizes on the MRI (ch2better), and the dynamic vs
# static balancer on a view where the volume covers only a corner of the screen.
#
#   bash bench/mpi_scaling.sh [--ranks "1 2 4"] [--sizes "1920x1080 5760x4320"] [--frames N]
#
# Prints markdown tables. Ranks beyond the machine's cores are oversubscribed (the table says
# so); each rank gets cores / ranks threads (at least one).
set -euo pipefail
cd "$(dirname "$0")/.."
ranks="1 2 4" sizes="1920x1080 5760x4320" frames=6
while [ $# -gt 0 ]; do
  case $1 in
    --ranks) ranks=$2; shift 2 ;;
    --sizes) sizes=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    *) echo "usage: $0 [--ranks LIST] [--sizes LIST] [--frames N]" >&2; exit 2 ;;
  esac
done
voxwall=${VOXWALL:-build/master/voxwall}
[ -x "$voxwall" ] || { echo "build first: bash scripts/build.sh" >&2; exit 1; }
work=$(mktemp -d "${TMPDIR:-/tmp}/voxwall-bench.XXXXXX")
trap 'rm -rf "$work"' EXIT
mri=/usr/share/mricron/templates/ch2better.nii.gz
[ -f "$mri" ] || { echo "needs Debian's mricron-data ($mri)" >&2; exit 1; }
"$voxwall" compress "$mri" -o "$work/mri.vwz" -q > /dev/null
mpi=(mpirun --oversubscribe --bind-to none)
[ "$(id -u)" = 0 ] && mpi+=(--allow-run-as-root)
cores=$(nproc)

echo "machine: $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')), $(date -u +%F)"
echo
echo "## Frame rate and imbalance (MRI, shaded, orbit 5 deg/frame, $frames frames, PNG written)"
echo
echo "| screen | ranks | threads/rank | frames/s | mean frame ms | mean imbalance | render % | wait for ranks % | assemble % | wait for writer % | encode+write ms/frame (background) | peak RSS rank 0 / others |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
for size in $sizes; do
  for n in $ranks; do
    threads=$((cores / n)); [ "$threads" -ge 1 ] || threads=1
    note=""; [ "$n" -gt "$cores" ] && note=" (oversubscribed)"
    out=$("${mpi[@]}" -np "$n" "$voxwall" render "$work/mri.vwz" --size "$size" --frames "$frames" \
      --orbit-deg 5 --shading --exact --out "$work/frames-$size-$n" 2>/dev/null)
    total=$(echo "$out" | grep '^total:' || true)
    fps=$(echo "$total" | sed -E 's/.* ([0-9.]+) frames\/s.*/\1/')
    mean=$(echo "$total" | sed -E 's/.*mean frame ([0-9.]+) ms.*/\1/')
    imb=$(echo "$total" | sed -E 's/.*mean imbalance ([0-9.]+).*/\1/')
    shares=$(echo "$out" | grep '^frame time on rank 0' | grep -oE '[0-9]+%' | tr -d % | paste -sd' ' || true)
    read -r render wait assemble writer <<< "$shares"
    write=$(echo "$out" | grep '^writer' | sed -E 's/.*write ([0-9.]+) ms.*/\1/' || true)
    rss0=$(echo "$out" | grep '^rank 0 on' | sed -E 's/.*peak (.*)$/\1/' || true)
    rss1=$(echo "$out" | grep '^rank 1 on' | sed -E 's/.*peak (.*)$/\1/' || true)
    echo "| $size | $n$note | $threads | $fps | $mean | $imb | $render | $wait | $assemble | $writer | $write | $rss0 / ${rss1:--} |"
    rm -rf "$work/frames-$size-$n"
  done
done

echo
echo "## Corner view: the volume covers the top-left corner (--pan 1.1,-0.55), still camera, 1920x1080"
echo
echo "Imbalance (slowest rank / mean) of each frame; frame 6 is cut from the costs of frames 1-5."
echo
header="| ranks | balance |"; rule="|---|---|"
for f in $(seq 1 8); do header="$header frame $f |"; rule="$rule---|"; done
echo "$header"; echo "$rule"
for n in 2 4; do
  [ "$n" -le 1 ] && continue
  for balance in static dynamic; do
    out=$("${mpi[@]}" -np "$n" "$voxwall" render "$work/mri.vwz" --size 1920x1080 --frames 8 \
      --orbit-deg 0 --pan 1.1,-0.55 --shading --exact --balance "$balance" --no-write 2>/dev/null)
    row=$(echo "$out" | grep -E '^frame [0-9]+/' | sed -E 's/.*imbalance ([0-9.]+).*/\1/' | paste -sd'|' || true)
    note=""; [ "$n" -gt "$cores" ] && note=" (oversubscribed)"
    echo "| $n$note | $balance | ${row//|/ | } |"
  done
done
