#!/usr/bin/env bash
# Multi-rank tests of `voxwall render` under mpirun, registered in ctest (tests/CMakeLists.txt)
# for several rank counts. Usage: mpi_test.sh VOXWALL MPIEXEC "PREFLAGS" SCENARIO [ARGS...]
#   equal N MODE      N ranks give the same frames as 1 rank, byte for byte (MODE: dynamic,
#                     static, tiles, master-only)
#   resume N          a run killed mid-way and resumed gives the same frames as an
#                     uninterrupted one
#   bad-volume N      a missing or truncated volume on one rank ends the job with one message
#   other-volume      a rank holding a different volume is refused
#   stall N           a rank that stops answering is named by the watchdog; the job ends
#   codecs N          for every codec of the build: N ranks give the same frames as 1 rank;
#                     the ranks share one file of decode tables (tvq's codebooks)
#   time N            a time series (vq and ksvd, per-step range too): N ranks render
#                     --time 0:3 with the same frames as 1 rank, every frame another step
#   dry-run N         prints the rank -> tile map, hosts and memory, renders nothing
#   memory-budget     a budget smaller than the volume is refused with the memory needed
#   sink N CODEC      N ranks stream to a `voxwall sink` on loopback (ci-2x2 wall): every display
#                     image equals (jpeg: >= 40 dB) the crop of the single-process render
#   sink-restart N    the sink is killed (-9) and restarted mid-run: the job goes on and reaches
#                     the new sink, every frame either sink wrote is whole and right
#   full-disk         render --out and the sink's --out on a full filesystem (a small tmpfs, or a
#                     file-size limit where mounting is not allowed): one line, non-zero exit, no
#                     partial frame under a final name; --resume then redoes exactly the missing
#                     and damaged frames
#   killed-writer     a sink killed (-9) while writing: no frame with a marker is partial, and
#                     the next sink on the folder clears what the killed one left
#   refused N         a render the sink refuses (wrong token) fails with one line, non-zero
#   hostile N         hostile peers (tests/tools/hostile_peers) flood the sink while N ranks
#                     render to it: every frame is presented and right, the sink keeps running
#   interactive N     a camera command typed at the sink: the next frames are interactive (1/4
#                     per side, upsampled, whole on every display), then, once the camera has
#                     settled and the picture refined, a full frame equal (>= 40 dB) to a batch
#                     render of that camera
#   abandon-burst N   200 camera commands, in bursts of 20 into successive frames, while N
#                     ranks render full frames (no reduced ones: every frame is one a
#                     command abandons): frames in flight are
#                     abandoned (reported as superseded), no rank hangs, every frame's fate is
#                     said, and the job ends on a full frame
# Needs VOXWALL_WALLS (the walls/ folder) and VOXWALL_COMPARE_CROP (tests/tools) for the sink
# scenarios; ctest sets both.
set -uo pipefail
# Under pipefail, `producer | grep -q` fails whenever grep's early exit gives the producer
# SIGPIPE (a resume check failed so, on a match): text is matched with here-strings
# (grep -q ... <<< "$out"), listings with a grep that reads them whole. (In a polling loop's
# `&& break` the race only costs one more round, so those are left as they are.)
voxwall=$1 mpiexec=$2 preflags=$3 scenario=$4
shift 4
work=$(mktemp -d "${TMPDIR:-/tmp}/voxwall-mpi.XXXXXX")
trap 'umount "$work"/*fs 2>/dev/null; rm -rf "$work"' EXIT
cd "$work"

fail() { echo "FAIL: $*" >&2; exit 1; }
# mpirun -np N voxwall ARGS... with a hard limit, so a hang fails the test instead of blocking.
run() {
  local n=$1
  shift
  # shellcheck disable=SC2086
  timeout -k 5 "${run_limit:-120}" "$mpiexec" $preflags -np "$n" "$voxwall" "$@"
}

"$voxwall" compress generated:shepp-logan:48 -o vol.vwz -q || fail "compress"
common=(render vol.vwz --size 97x61 --frames 4 --orbit-deg 20 --shading -q --threads 1)

descendants() {
  local child
  for child in $(pgrep -P "$1"); do
    descendants "$child"
    echo "$child"
  done
}

frames_in() { ls "$1" | grep -E '^frame_[0-9]+\.png$'; }

same_frames() {
  local a=$1 b=$2 count=0
  for f in $(frames_in "$a"); do
    cmp -s "$a/$f" "$b/$f" || fail "$f differs between $a and $b"
    count=$((count + 1))
  done
  [ "$count" -gt 0 ] || fail "no frames in $a"
  [ "$count" -eq "$(frames_in "$b" | wc -l)" ] || fail "$a and $b hold different frame sets"
}

# Starts a sink on a free loopback port (PORT=... when given); sets sink_pid and sink_port.
start_sink() {
  local out=$1 frames=$2 port=${3:-0}
  # Cleared here, not by the child's redirection: a restart on the same log must not let
  # wait_port read the previous sink's "listening" line before the child truncates the file.
  rm -f "$out.log"
  "$voxwall" sink --wall "$VOXWALL_WALLS/ci-2x2.json" --listen "127.0.0.1:$port" --out "$out" \
    --frames "$frames" --no-stdin > "$out.log" 2>&1 &
  sink_pid=$!
  wait_port "$out.log"
}

# Waits until the sink logging to LOG listens; sets sink_port.
wait_port() {
  for _ in $(seq 200); do
    sink_port=$(sed -n 's/.*listening on 127.0.0.1:\([0-9]*\).*/\1/p' "$1" 2>/dev/null)
    [ -n "$sink_port" ] && return 0
    sleep 0.05
  done
  cat "$1"
  fail "the sink did not start"
}

# Every frame the sink wrote to DIR (those with a frame_N.done marker) is whole (4 displays) and
# matches the reference frames in REF (min PSNR given: at least that; else equal); no display
# picture lies there without its marker. Prints how many frames it checked.
check_wall_frames() {
  local dir=$1 ref=$2 psnr=${3:-} checked=0
  declare -A rects=([r0c0]="0 0" [r0c1]="100 0" [r1c0]="0 68" [r1c1]="100 68")
  for f in $(ls "$dir" | sed -n 's/^frame_\([0-9]*\)_r[01]c[01].png$/\1/p' | sort -u); do
    [ -f "$dir/frame_$f.done" ] || fail "frame $f in $dir has pictures but no marker (a partial frame)"
  done
  ls "$dir" | grep '\.tmp\.' > /dev/null && fail "temporary files left in $dir"
  for f in $(ls "$dir" | sed -n 's/^frame_\([0-9]*\)\.done$/\1/p'); do
    for d in r0c0 r0c1 r1c0 r1c1; do
      [ -f "$dir/frame_${f}_$d.png" ] || fail "frame $f in $dir lacks display $d (a partial frame)"
      # shellcheck disable=SC2086
      "$VOXWALL_COMPARE_CROP" "$ref/frame_$f.png" ${rects[$d]} 96 64 "$dir/frame_${f}_$d.png" \
        $psnr > /dev/null || fail "frame $f display $d differs from the single-process render"
    done
    checked=$((checked + 1))
  done
  for other in $(ls "$dir" | sed -n 's/^frame_\([0-9]*\)_r[01]c[01].png$/\1/p' | sort -u); do
    [ -f "$dir/frame_${other}_r0c0.png" ] || fail "frame $other in $dir lacks display r0c0"
  done
  echo "$checked"
}

# Starts a sink on DIR and stops it once it listens: it clears what a killed sink left there.
clear_with_sink() {
  local dir=$1
  start_sink "$dir" 0
  kill -TERM "$sink_pid"; wait "$sink_pid" 2>/dev/null
  mv "$dir.log" "$dir.clear.log"
}

# Makes DIR (named *fs, so the exit trap unmounts it) a filesystem of SIZE kilobytes (tmpfs) and
# prints "mounted"; where mounting is not allowed, prints "ulimit" and the caller runs the writer
# under `ulimit -f` instead.
small_fs() {
  local dir=$1 size=$2
  mkdir -p "$dir"
  if mount -t tmpfs -o "size=${size}k" tmpfs "$dir" 2>/dev/null; then
    echo mounted
  else
    echo ulimit
  fi
}

# Runs the rest of the line with a per-file size limit of $1 KiB when $2 is "ulimit".
limited() {
  local kib=$1 how=$2
  shift 2
  if [ "$how" = ulimit ]; then
    (ulimit -f "$kib"; trap '' XFSZ; exec "$@")
  else
    "$@"
  fi
}

case $scenario in
  interactive)
    n=$1
    mkfifo commands
    # The writer may drop the oldest frame it holds when it falls behind a stream of small
    # frames (on a loaded machine it did, with the default queue of 8): the test needs the
    # interactive frame's files, so the queue is deep enough for the whole exchange.
    "$voxwall" sink --wall "$VOXWALL_WALLS/ci-2x2.json" --listen 127.0.0.1:0 --out wall \
      --write-queue 1024 < commands > wall.log 2>&1 &
    sink_pid=$!
    exec 3> commands  # the sink's stdin, held open
    wait_port wall.log
    run "$n" render vol.vwz --wall "$VOXWALL_WALLS/ci-2x2.json" --sink "127.0.0.1:$sink_port" \
      --frames 100000 --path still --threads 1 --interactive-step 4 --settle 1 -q \
      > render.log 2>&1 &
    render_pid=$!
    for _ in $(seq 600); do grep -q "presented" wall.log && break; sleep 0.05; done
    grep -q "presented" wall.log || { cat wall.log render.log; fail "the sink showed nothing"; }
    echo "rotate 30 0" >&3
    # An interactive frame, then a full one after it.
    reduced="" settled=""
    for _ in $(seq 1200); do
      reduced=$(sed -n 's/^frame \([0-9]*\) presented.*interactive 1\/4.*/\1/p' wall.log | head -1)
      if [ -n "$reduced" ]; then
        settled=$(awk -v r="$reduced" '/presented/ && !/ 1\// {
                    n = $2 + 0; if (n > r) { print n; exit } }' wall.log)
        [ -n "$settled" ] && [ -f "wall/frame_$(printf %05d "$settled").done" ] && break
      fi
      sleep 0.05
    done
    kill -TERM "$render_pid" 2>/dev/null; wait "$render_pid" 2>/dev/null
    exec 3>&-
    kill -TERM "$sink_pid" 2>/dev/null; wait "$sink_pid" 2>/dev/null
    [ -n "$reduced" ] || { cat wall.log; fail "no interactive frame after the command"; }
    [ -n "$settled" ] || { tail wall.log; fail "no full frame after the interactive ones"; }
    "$voxwall" render vol.vwz --size 196x132 --camera 60,20,2.6 --frames 1 --threads 1 -q \
      --out ref || fail "reference render"
    declare -A rects=([r0c0]="0 0" [r0c1]="100 0" [r1c0]="0 68" [r1c1]="100 68")
    r=$(printf %05d "$reduced") s=$(printf %05d "$settled")
    for d in r0c0 r0c1 r1c0 r1c1; do
      if [ ! -f "wall/frame_${r}_$d.png" ]; then
        grep "^frame $reduced " wall.log
        fail "interactive frame $reduced lacks display $d"
      fi
      # shellcheck disable=SC2086
      "$VOXWALL_COMPARE_CROP" ref/frame_00000.png ${rects[$d]} 96 64 "wall/frame_${s}_$d.png" 40 \
        > /dev/null || fail "settled frame $settled display $d differs from the batch render"
      # The interactive frame is the same picture, coarser: not blank, not another view.
      # shellcheck disable=SC2086
      "$VOXWALL_COMPARE_CROP" ref/frame_00000.png ${rects[$d]} 96 64 "wall/frame_${r}_$d.png" 15 \
        > /dev/null || fail "interactive frame $reduced display $d is not the batch render's picture"
    done
    echo "interactive frame $reduced, then full frame $settled equal to the batch render"
    ;;
  abandon-burst)
    n=$1 frames=200
    mkfifo commands
    "$voxwall" sink --wall "$VOXWALL_WALLS/ci-2x2.json" --listen 127.0.0.1:0 \
      < commands > wall.log 2>&1 &
    sink_pid=$!
    exec 3> commands  # the sink's stdin, held open
    wait_port wall.log
    run "$n" render vol.vwz --wall "$VOXWALL_WALLS/ci-2x2.json" --sink "127.0.0.1:$sink_port" \
      --frames "$frames" --path still --threads 1 --shading --interactive-step 1 \
      > render.log 2>&1 &
    render_pid=$!
    # Waits on the sink's log itself (tail -f), with a deadline.
    timeout 30 grep -m1 -q "presented" <(tail -f wall.log) ||
      { cat wall.log render.log; fail "the sink showed nothing"; }
    # 200 commands straight into the frames in flight: 10 bursts of 20, each burst once the sink
    # settled another frame since the last one (waiting on its log, with a deadline), so the
    # bursts land in successive frames however fast the machine renders.
    for _ in $(seq 10); do
      kill -0 "$render_pid" 2>/dev/null || break
      lines=$(wc -l < wall.log)
      for _ in $(seq 20); do echo "rotate 1 0" >&3; done
      timeout 30 grep -m1 -qE "^frame [0-9]+ (presented|superseded)" \
        <(tail -n +"$((lines + 1))" -f wall.log) || break
    done
    wait "$render_pid"
    status=$?
    exec 3>&-
    kill -TERM "$sink_pid" 2>/dev/null
    wait "$sink_pid" 2>/dev/null
    [ "$status" -eq 0 ] || { tail -20 render.log; fail "the render exited $status"; }
    summary=$(grep "frame(s) presented" wall.log) || { tail wall.log; fail "no sink summary"; }
    presented=$(echo "$summary" | sed -n 's/^sink: \([0-9]*\) frame(s) presented.*/\1/p')
    dropped=$(echo "$summary" | sed -n 's/.*, \([0-9]*\) dropped incomplete.*/\1/p')
    superseded=$(grep -c "^frame [0-9]* superseded" wall.log)
    [ $((presented + dropped + superseded)) -eq "$frames" ] ||
      { echo "$summary"; fail "$presented presented, $dropped dropped, $superseded superseded: not $frames"; }
    abandoned=$(grep -c "abandoned: the camera moved" render.log)
    [ "$abandoned" -eq "$superseded" ] ||
      fail "rank 0 abandoned $abandoned frame(s), the sink superseded $superseded"
    last=$(grep "presented" wall.log | grep -v "frame(s) presented" | tail -1)
    grep -q " 1/" <<< "$last" && fail "the job did not end on a full frame: $last"
    echo "$presented presented, $superseded abandoned and superseded, $dropped dropped; $last"
    ;;
  full-disk)
    frames=(render vol.vwz --size 240x160 --frames 12 --orbit-deg 30 --threads 1)
    "$voxwall" "${frames[@]}" -q --out ref || fail "reference render"
    # Frames are 13-15 KB: the disk fills after a few; a per-file limit fails the larger ones.
    how=$(small_fs fullfs 64)
    limited 14 "$how" "$voxwall" "${frames[@]}" -q --out fullfs/frames 2> render.err
    status=$?
    [ "$status" -ne 0 ] || fail "render on a full disk exited 0"
    [ "$(grep -c 'cannot write' render.err)" -eq 1 ] || { cat render.err; fail "not one error line"; }
    grep -qE "voxwall: .*fullfs/frames/(frame_[0-9]+\.png|voxwall-job\.json).*: cannot write: (No space left on device|File too large)" render.err \
      || { cat render.err; fail "the error line does not name the file and the reason"; }
    # Every frame under its final name is whole. Those the manifest recorded are kept on
    # --resume; one renamed into place just before the manifest could be written is redone.
    for f in $(frames_in fullfs/frames); do
      cmp -s "fullfs/frames/$f" "ref/$f" || fail "$f under its final name differs (partial?)"
    done
    ls fullfs/frames | grep '\.tmp\.' > /dev/null && fail "temporaries left on the full disk"
    recorded=$(grep -oE '"frame_[0-9]+\.png": \{' fullfs/frames/voxwall-job.json | tr -d '":{ ')
    kept=$(echo "$recorded" | grep -c png)
    cp -r fullfs/frames roomy
    # A frame damaged after it was recorded is rendered again on --resume.
    damaged=$(echo "$recorded" | grep png | head -1)
    if [ -n "$damaged" ]; then
      truncate -s 100 "roomy/$damaged"
      kept=$((kept - 1))
    fi
    out=$("$voxwall" "${frames[@]}" --out roomy --resume 2> resume.err) || { cat resume.err; fail "resume"; }
    if [ "$kept" -gt 0 ]; then
      grep -q "resume: $kept frame(s) already complete" <<< "$out" || { echo "$out"; fail "resume kept other than the $kept whole frames"; }
    else
      grep -q "resume:" <<< "$out" && { echo "$out"; fail "resume kept frames the manifest does not hold"; }
    fi
    [ -z "$damaged" ] || grep -q "roomy/$damaged: not as the job manifest recorded it" resume.err \
      || { cat resume.err; fail "the damaged frame was not named"; }
    same_frames ref roomy
    # The sink on a full disk: one line, non-zero, and no frame without all its pictures.
    # A frame is about 22 KB (four displays and the 10 KB mosaic).
    how=$(small_fs wallfs 100)
    limited 8 "$how" "$voxwall" sink --wall "$VOXWALL_WALLS/ci-2x2.json" --listen 127.0.0.1:0 \
      --out wallfs/w --mosaic --frames 0 --no-stdin > wallfs.log 2> wallfs.err &
    sink_pid=$!
    wait_port wallfs.log
    "$voxwall" render vol.vwz --wall "$VOXWALL_WALLS/ci-2x2.json" --sink "127.0.0.1:$sink_port" \
      --tile-codec deflate --frames 12 --orbit-deg 30 --threads 1 -q > /dev/null 2>&1
    timeout 30 tail --pid="$sink_pid" -f /dev/null || fail "the sink on a full disk kept running"
    wait "$sink_pid"
    [ $? -ne 0 ] || fail "the sink on a full disk exited 0"
    grep -qE "voxwall: .*wallfs/w/frame_[0-9]+_.*png: cannot write: (No space left on device|File too large)" wallfs.err \
      || { cat wallfs.log wallfs.err; fail "the sink's error does not name the file and the reason"; }
    "$voxwall" render vol.vwz --size 196x132 --frames 12 --orbit-deg 30 --threads 1 -q \
      --out wallref || fail "reference render"
    shown=$(check_wall_frames wallfs/w wallref) || exit 1
    echo "full disk ($how): render kept $kept whole frame(s) and failed with one line; resume" \
      "redid the rest; the sink showed $shown whole frame(s) and stopped with one line"
    ;;
  killed-writer)
    start_sink wall 0
    "$voxwall" render vol.vwz --wall "$VOXWALL_WALLS/ci-2x2.json" --sink "127.0.0.1:$sink_port" \
      --tile-codec deflate --frames 40 --orbit-deg 20 --threads 1 -q > render.log 2>&1 &
    render_pid=$!
    for _ in $(seq 400); do ls wall | grep -q '\.done$' && break; sleep 0.02; done
    ls wall | grep '\.done$' > /dev/null || fail "the sink wrote nothing"
    kills=0
    # Kill it again and again mid-frame, restarting it on the same folder each time.
    for delay in 0.01 0.03 0.05 0.07 0.11; do
      sleep "$delay"
      kill -KILL "$sink_pid"; wait "$sink_pid" 2>/dev/null
      kills=$((kills + 1))
      start_sink wall 0 "$sink_port"
      grep -q "listening" wall.log || fail "the sink did not restart"
    done
    wait "$render_pid" || { cat render.log; fail "the render job did not survive"; }
    kill -TERM "$sink_pid"; wait "$sink_pid" 2>/dev/null
    clear_with_sink wall
    "$voxwall" render vol.vwz --size 196x132 --frames 40 --orbit-deg 20 --threads 1 -q \
      --out ref || fail "reference render"
    shown=$(check_wall_frames wall ref) || exit 1
    [ "$shown" -ge 1 ] || fail "no frame survived"
    echo "killed the sink $kills times while writing: $shown whole frame(s), no partial one"
    ;;
  refused)
    n=$1
    "$voxwall" sink --wall "$VOXWALL_WALLS/ci-2x2.json" --listen 127.0.0.1:0 --token right \
      --no-stdin > sink.log 2>&1 &
    sink_pid=$!
    wait_port sink.log
    run "$n" render vol.vwz --wall "$VOXWALL_WALLS/ci-2x2.json" --sink "127.0.0.1:$sink_port" \
      --token wrong --frames 30 --threads 1 -q > render.log 2>&1
    status=$?
    kill -TERM "$sink_pid"; wait "$sink_pid" 2>/dev/null
    [ "$status" -ne 0 ] || { cat render.log; fail "a refused render exited 0"; }
    grep -q "refused: .*wrong token" render.log || { cat render.log; fail "no line says why"; }
    echo "refused render: exit $status, $(grep -m1 'wrong token' render.log)"
    ;;
  hostile)
    n=$1
    frames=8
    start_sink wall "$frames"
    # Frames slow enough (--step) that the sink's writer keeps up and skips none for being behind.
    run "$n" render vol.vwz --wall "$VOXWALL_WALLS/ci-2x2.json" --sink "127.0.0.1:$sink_port" \
      --tile-codec deflate --frames "$frames" --orbit-deg 20 --step 0.02 --threads 1 -q \
      > render.log 2>&1 &
    render_pid=$!
    # The peers come once the job holds the wall: before that, any peer without a token may take
    # it (docs/wall.md), which is not what this test is about.
    for _ in $(seq 400); do grep -q "job .* started" wall.log && break; sleep 0.02; done
    "$VOXWALL_HOSTILE_PEERS" "$sink_port" 600 > hostile.log 2>&1 &
    hostile_pid=$!
    wait "$render_pid" || { cat render.log; fail "the render job failed"; }
    timeout 60 tail --pid="$sink_pid" -f /dev/null || fail "the sink did not finish"
    wait "$sink_pid" || { tail wall.log; fail "the sink exited with $?"; }
    kill -TERM "$hostile_pid"; wait "$hostile_pid" 2>/dev/null
    for f in $(seq 0 $((frames - 1))); do
      grep -q "frame $f presented" wall.log || { cat wall.log; fail "frame $f was not presented"; }
    done
    "$voxwall" render vol.vwz --size 196x132 --frames "$frames" --orbit-deg 20 --step 0.02 \
      --threads 1 -q --out ref || fail "reference render"
    shown=$(check_wall_frames wall ref) || exit 1
    cat hostile.log
    [ "$shown" -eq "$frames" ] || fail "$shown of $frames frames on the wall"
    refused=$(grep -c "sink: refused" wall.log)
    dropped=$(grep -c "sink: dropped" wall.log)
    echo "all $frames frames presented and right while the sink refused $refused and dropped" \
      "$dropped hostile peers"
    ;;
  equal)
    n=$1 mode=$2
    "$voxwall" "${common[@]}" --out ref || fail "single-process reference"
    case $mode in
      dynamic) extra=(--balance dynamic --cost-cell 8) ;;
      static) extra=(--balance static) ;;
      tiles) extra=(--tiles 5x3) ;;
      master-only) extra=(--master-only) ;;
      *) fail "unknown mode $mode" ;;
    esac
    run "$n" "${common[@]}" "${extra[@]}" --out multi || fail "mpirun -np $n exited with $?"
    same_frames ref multi
    ;;
  codecs)
    # Every codec of the build (`voxwall codecs --list`), with its example options (lossy where
    # the codec can be): every rank renders from the compressed volume through its own view and
    # caches, byte for byte like one process; codecs with mip levels also with nearest sampling.
    n=$1
    "$voxwall" codecs --list > codecs.txt || fail "voxwall codecs --list"
    # Read the list first: mpirun forwards its stdin to rank 0 and would eat the rest of it.
    mapfile -t codec_lines < codecs.txt
    [ ${#codec_lines[@]} -gt 0 ] || fail "no codecs listed"
    for line in "${codec_lines[@]}"; do
      IFS=$'\t' read -r name _id levels options <<< "$line"
      # shellcheck disable=SC2086
      "$voxwall" compress generated:shepp-logan:48 --codec "$name" $options -o "$name.vwz" -q ||
        fail "compress --codec $name $options"
      args=(render "$name.vwz" --size 97x61 --frames 4 --orbit-deg 20 --shading -q --threads 1)
      "$voxwall" "${args[@]}" --out "ref-$name" || fail "$name: single-process reference"
      run "$n" "${args[@]}" --balance dynamic --cost-cell 8 --out "multi-$name" ||
        fail "$name: mpirun -np $n exited with $?"
      same_frames "ref-$name" "multi-$name"
      if [ "$levels" = levels ]; then
        "$voxwall" "${args[@]}" --sampling nearest --out "nref-$name" ||
          fail "$name: single-process nearest"
        run "$n" "${args[@]}" --sampling nearest --out "nmulti-$name" ||
          fail "$name: mpirun nearest exited with $?"
        same_frames "nref-$name" "nmulti-$name"
      fi
      echo "$name: $n ranks equal one process"
    done
    # The ranks (all on this host) agreed on one file for the tables a codec makes to decode
    # (tvq's codebooks, made by one rank and read by the others in the frames above), and each
    # rank's memory line gives its share of it apart from its private memory.
    run "$n" render tvq.vwz --size 97x61 --frames 1 --threads 1 --no-write -v > tables.out 2>&1 ||
      { cat tables.out; fail "tvq -v: mpirun -np $n exited with $?"; }
    grep -q "^voxwall: value ranges and decode tables made once a host: $n rank(s) on 1 host(s) share them$" \
      tables.out || { cat tables.out; fail "the ranks did not share one file of decode tables"; }
    [ "$(grep -c '^rank [0-9]* on .*; private .*, shared .* (its share), mapped files ' \
      tables.out)" -eq "$n" ] || { cat tables.out; fail "no memory line with a shared part"; }
    ;;
  time)
    # Each frame's step travels in the frame task: every rank opens that step, byte for byte
    # like one process, and consecutive frames show different steps.
    n=$1
    "$voxwall" generate blobs --steps 4 --size 40 -o blobs.nii > /dev/null || fail "generate"
    for codec in vq ksvd; do
      "$voxwall" compress blobs.nii --codec "$codec" -o "$codec.vwz" -q || fail "compress $codec"
      for range in series per-step; do
        args=(render "$codec.vwz" --size 97x61 --time 0:3 --range "$range" --shading -q
          --threads 1 --path still)
        "$voxwall" "${args[@]}" --out "ref-$codec-$range" || fail "$codec: single process"
        run "$n" "${args[@]}" --balance dynamic --cost-cell 8 --out "multi-$codec-$range" ||
          fail "$codec $range: mpirun -np $n exited with $?"
        same_frames "ref-$codec-$range" "multi-$codec-$range"
        [ "$(ls "multi-$codec-$range"/frame_*.png | wc -l)" = 4 ] || fail "not 4 frames"
        cmp -s "multi-$codec-$range/frame_00000.png" "multi-$codec-$range/frame_00002.png" &&
          fail "$codec: steps 0 and 2 gave the same frame"
      done
      echo "$codec: a series on $n ranks equals one process"
    done
    ;;
  resume)
    n=$1
    slow=(render vol.vwz --size 240x160 --frames 30 --step 0.04 --shading --threads 1)
    run "$n" "${slow[@]}" -q --out ref || fail "uninterrupted run"
    run "$n" "${slow[@]}" -q --out killed &
    pid=$!
    for _ in $(seq 600); do [ -f killed/frame_00002.png ] && break; sleep 0.05; done
    [ -f killed/frame_00002.png ] || fail "no frame appeared before the kill"
    # Kill the whole tree at once (timeout, mpirun and every rank), as a node failure would.
    tree="$(descendants "$pid") $pid"
    # shellcheck disable=SC2086
    kill -STOP $tree 2>/dev/null; kill -KILL $tree 2>/dev/null; wait "$pid" 2>/dev/null
    # Complete frames are those the job manifest records (with their size and hash); a frame
    # renamed into place just before the kill, but not yet recorded, is rendered again.
    done_before=$(grep -cE '"frame_[0-9]+\.png": \{' killed/voxwall-job.json || true)
    [ "$done_before" -lt 30 ] || fail "the run finished before it could be killed"
    out=$(run "$n" "${slow[@]}" --out killed --resume) || fail "resumed run"
    grep -q "resume: $done_before frame(s) already complete" <<< "$out" || fail "resume did not skip the $done_before complete frames: $out"
    out=$(run "$n" "${slow[@]}" --out killed --resume) || fail "second resume"
    grep -q "resume: 30 frame(s) already complete" <<< "$out" || fail "second resume rendered frames again: $out"
    same_frames ref killed
    ls killed | grep '\.tmp\.' > /dev/null && fail "temporary files left behind"
    echo "killed after $done_before complete frames; resumed to the same 30 frames"
    ;;
  bad-volume)
    n=$1
    head -c 3000 vol.vwz > truncated.vwz
    for bad in missing.vwz truncated.vwz; do
      # shellcheck disable=SC2086
      timeout -k 5 120 "$mpiexec" $preflags -np $((n - 1)) "$voxwall" render vol.vwz --no-write \
        --size 64x48 : -np 1 "$voxwall" render "$bad" --no-write --size 64x48 > out.txt 2> err.txt
      status=$?
      [ "$status" -ne 0 ] || fail "$bad on rank $((n - 1)): exit status 0"
      [ "$status" -ne 124 ] && [ "$status" -ne 137 ] || fail "$bad: the job hung"
      grep -q "^voxwall: rank $((n - 1)) (.*): .*$bad" err.txt || { cat err.txt; fail "$bad: no message naming rank $((n - 1)) and the file"; }
      [ "$(grep -c '^voxwall:' err.txt)" -eq 1 ] || { cat err.txt; fail "$bad: more than one error line"; }
    done
    ;;
  other-volume)
    "$voxwall" compress generated:shepp-logan:40 -o other.vwz -q || fail "compress"
    # shellcheck disable=SC2086
    timeout -k 5 120 "$mpiexec" $preflags -np 1 "$voxwall" render vol.vwz --no-write --size 64x48 \
      : -np 1 "$voxwall" render other.vwz --no-write --size 64x48 > out.txt 2> err.txt
    [ $? -ne 0 ] || fail "different volumes were accepted"
    grep -q "rank 1 (.*) holds a different volume" err.txt || { cat err.txt; fail "no message"; }
    ;;
  stall)
    # The last rank stops answering mid-job, as a hung rank would: it is stopped (SIGSTOP) once
    # the job has rendered a frame. The watchdog on rank 0 must name it and end the job.
    n=$1
    victim_rank=$((n - 1))
    start=$(date +%s)
    run "$n" render vol.vwz --size 64x48 --frames 100000 --no-write --watchdog 2 --threads 1 \
      > out.txt 2> err.txt &
    job=$!
    for _ in $(seq 300); do grep -q '^frame 2/' out.txt && break; sleep 0.1; done
    grep -q '^frame 2/' out.txt || { cat err.txt; fail "the job did not start rendering"; }
    victim=
    for p in $(descendants "$job"); do
      if tr '\0' '\n' < "/proc/$p/environ" 2> /dev/null |
        grep -qx "OMPI_COMM_WORLD_RANK=$victim_rank"; then
        victim=$p
        break
      fi
    done
    [ -n "$victim" ] || fail "found no process of rank $victim_rank"
    kill -STOP "$victim"
    wait "$job"
    status=$?
    kill -KILL "$victim" 2> /dev/null
    elapsed=$(($(date +%s) - start))
    [ "$status" -ne 0 ] || fail "a stalled rank went unnoticed"
    [ "$status" -ne 124 ] && [ "$status" -ne 137 ] || fail "the job hung until the test's timeout"
    # Stopped after its report, it takes no frame task; stopped before, it sends no report. (A
    # frame task small enough for the shared-memory transport's fast path completes without
    # the receiver: those were always the report.)
    grep -Eq "watchdog: rank $victim_rank did not (report|take the frame task)" err.txt || { cat err.txt; fail "the watchdog did not name rank $victim_rank"; }
    [ "$elapsed" -lt 60 ] || fail "took $elapsed s to notice"
    echo "stalled rank $victim_rank named after $elapsed s"
    ;;
  dry-run)
    n=$1
    run "$n" render vol.vwz --size 640x480 --dry-run --out dry > out.txt 2> err.txt || { cat err.txt; fail "dry run failed"; }
    [ "$(grep -c '^rank [0-9]* on .*: needs .*; tiles: [0-9]*x[0-9]*+0+[0-9]*$' out.txt)" -eq "$n" ] || { cat out.txt; fail "no tile map"; }
    [ ! -e dry ] || fail "a dry run wrote frames"
    ;;
  memory-budget)
    run 2 render vol.vwz --size 640x480 --no-write --memory-budget 64K > out.txt 2> err.txt
    [ $? -ne 0 ] || fail "a 64 KiB budget was accepted"
    grep -q "needs .* over the --memory-budget of 64.0 KiB" err.txt || { cat err.txt; fail "no message saying what is needed"; }
    run 2 render vol.vwz --size 64x48 --no-write --memory-budget 4G -q || fail "a 4 GiB budget was refused"
    ;;
  sink)
    n=$1 codec=$2
    start_sink wall 3
    run "$n" render vol.vwz --wall "$VOXWALL_WALLS/ci-2x2.json" --sink "127.0.0.1:$sink_port" \
      --tile-codec "$codec" --frames 3 --orbit-deg 20 --threads 1 -q || fail "render to the sink"
    timeout 30 tail --pid="$sink_pid" -f /dev/null || fail "the sink did not finish"
    wait "$sink_pid" || fail "the sink exited with $?"
    "$voxwall" render vol.vwz --size 196x132 --frames 3 --orbit-deg 20 --threads 1 -q --out ref \
      || fail "reference render"
    psnr=""; [ "$codec" = jpeg ] && psnr=40
    checked=$(check_wall_frames wall ref $psnr) || exit 1
    [ "$checked" -ge 1 ] || fail "the sink showed no frame"
    grep -q "frame 2 presented" wall.log || { cat wall.log; fail "the newest frame was not shown"; }
    echo "$checked frame(s) on the wall match the single-process render"
    ;;
  sink-restart)
    n=$1
    # Slow frames (--step 0.01) so the sink dies mid-job. The job has far more frames than the
    # test needs: it runs until the restarted sink has presented a frame (waited on with a
    # deadline), then it is stopped, so how fast the machine renders does not matter.
    run_limit=300
    start_sink first 0
    port=$sink_port
    slow=(render vol.vwz --wall "$VOXWALL_WALLS/ci-2x2.json" --sink "127.0.0.1:$port"
          --tile-codec deflate --frames 100000 --orbit-deg 9 --step 0.01 --threads 1)
    run "$n" "${slow[@]}" > render.log 2>&1 &
    render_pid=$!
    timeout 120 grep -m1 -q "presented" <(tail -f first.log) ||
      { cat first.log render.log; fail "the first sink showed nothing"; }
    kill -KILL "$sink_pid"; wait "$sink_pid" 2>/dev/null
    start_sink second 0 "$port"
    second_pid=$sink_pid
    timeout 200 grep -m1 -q "^frame [0-9]* presented" <(tail -f second.log) ||
      { cat second.log render.log; fail "no frame reached the restarted sink"; }
    kill -0 "$render_pid" 2>/dev/null ||
      { cat render.log; fail "the render job did not survive the sink's restart"; }
    kill -TERM "$render_pid" 2>/dev/null; wait "$render_pid" 2>/dev/null
    kill -TERM "$second_pid" 2>/dev/null; wait "$second_pid" 2>/dev/null
    clear_with_sink first
    # The reference covers every frame either sink wrote.
    last=$(ls first second | sed -n 's/^frame_\([0-9]*\)\.done$/\1/p' | sort -n | tail -1)
    [ -n "$last" ] || fail "neither sink wrote a whole frame"
    last=$((10#$last))
    "$voxwall" render vol.vwz --size 196x132 --frames $((last + 1)) --orbit-deg 9 --step 0.01 \
      --threads 1 -q --out ref || fail "reference render"
    a=$(check_wall_frames first ref) || exit 1
    b=$(check_wall_frames second ref) || exit 1
    [ "$b" -ge 1 ] || { cat second.log; fail "the restarted sink wrote no whole frame"; }
    [ $((a + b)) -lt $((last + 1)) ] || fail "no frame was lost while the sink was down?"
    echo "first sink showed $a frame(s), the restarted one $b (up to frame $last), all whole and right"
    ;;
  *)
    fail "unknown scenario $scenario"
    ;;
esac
echo "PASS: $scenario $*"
