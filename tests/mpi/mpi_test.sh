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
#   dry-run N         prints the rank -> tile map, hosts and memory, renders nothing
#   memory-budget     a budget smaller than the volume is refused with the memory needed
set -uo pipefail
voxwall=$1 mpiexec=$2 preflags=$3 scenario=$4
shift 4
work=$(mktemp -d "${TMPDIR:-/tmp}/voxwall-mpi.XXXXXX")
trap 'rm -rf "$work"' EXIT
cd "$work"

fail() { echo "FAIL: $*" >&2; exit 1; }
# mpirun -np N voxwall ARGS... with a hard limit, so a hang fails the test instead of blocking.
run() {
  local n=$1
  shift
  # shellcheck disable=SC2086
  timeout -k 5 120 "$mpiexec" $preflags -np "$n" "$voxwall" "$@"
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

same_frames() {
  local a=$1 b=$2 count=0
  for f in "$a"/frame_*.png; do
    cmp -s "$f" "$b/$(basename "$f")" || fail "$(basename "$f") differs between $a and $b"
    count=$((count + 1))
  done
  [ "$count" -gt 0 ] || fail "no frames in $a"
  [ "$count" -eq "$(ls "$b"/frame_*.png | wc -l)" ] || fail "$a and $b hold different frame sets"
}

case $scenario in
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
    done_before=$(ls killed/frame_*.png | wc -l)
    [ "$done_before" -lt 30 ] || fail "the run finished before it could be killed"
    out=$(run "$n" "${slow[@]}" --out killed --resume) || fail "resumed run"
    echo "$out" | grep -q "resume: $done_before frame(s) already complete" || fail "resume did not skip the $done_before complete frames: $out"
    out=$(run "$n" "${slow[@]}" --out killed --resume) || fail "second resume"
    echo "$out" | grep -q "resume: 30 frame(s) already complete" || fail "second resume rendered frames again: $out"
    same_frames ref killed
    ls killed | grep -q '\.tmp\.' && fail "temporary files left behind"
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
    n=$1
    start=$(date +%s)
    run "$n" render vol.vwz --size 64x48 --frames 6 --no-write --watchdog 2 \
      --test-stall-rank $((n - 1)) --test-stall-call 1 > out.txt 2> err.txt
    status=$?
    elapsed=$(($(date +%s) - start))
    [ "$status" -ne 0 ] || fail "a stalled rank went unnoticed"
    [ "$status" -ne 124 ] && [ "$status" -ne 137 ] || fail "the job hung until the test's timeout"
    grep -q "watchdog: rank $((n - 1)) did not report" err.txt || { cat err.txt; fail "the watchdog did not name rank $((n - 1))"; }
    [ "$elapsed" -lt 60 ] || fail "took $elapsed s to notice"
    echo "stalled rank $((n - 1)) named after $elapsed s"
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
  *)
    fail "unknown scenario $scenario"
    ;;
esac
echo "PASS: $scenario $*"
