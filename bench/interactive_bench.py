#!/usr/bin/env python3
"""Frame rate while steering against the full-resolution rate, on one wall, in one run.

Starts `voxwall sink` for the wall with camera commands on its stdin, renders the volume on
N MPI ranks streaming to it with `--path still`, lets it render full frames, then types a
`rotate` command every 0.1 s (what a drag in the wall page sends) for a while, and reads the
render job's per-frame lines: frames marked "interactive 1/S" against the full ones.

Usage: interactive_bench.py [--voxwall BIN] [--wall walls/bigeye.json] [--volume FILE]
                            [--ranks 2] [--full 2] [--drag-seconds 20] [--shading]
Prints a table; stops with an error when it cannot parse what it measured.
"""
import argparse
import os
import queue
import re
import statistics
import subprocess
import sys
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LINE = re.compile(r"^frame (\d+)/\d+: ([0-9.]+) ms, .*?-> sink: .*")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--voxwall", default=os.path.join(ROOT, "build/master/voxwall"))
    ap.add_argument("--wall", default=os.path.join(ROOT, "walls/bigeye.json"))
    ap.add_argument("--volume", default="/usr/share/mricron/templates/ch2better.nii.gz")
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--full", type=int, default=2, help="full frames before the drag")
    ap.add_argument("--drag-seconds", type=float, default=20)
    ap.add_argument("--step", type=int, default=4, help="--interactive-step")
    ap.add_argument("--shading", action="store_true")
    ap.add_argument("--out", default=os.path.join(ROOT, "bench-out"))
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    vwz = os.path.join(args.out, "interactive.vwz")
    subprocess.run([args.voxwall, "compress", args.volume, "-o", vwz, "-q"], check=True,
                   stdout=subprocess.DEVNULL)
    sink_log = open(os.path.join(args.out, "interactive-sink.log"), "w")
    sink = subprocess.Popen([args.voxwall, "sink", "--wall", args.wall, "--listen",
                             "127.0.0.1:0"], stdin=subprocess.PIPE, stdout=sink_log,
                            stderr=subprocess.STDOUT, text=True)
    port = None
    for _ in range(200):
        m = re.search(r"listening on 127\.0\.0\.1:(\d+)",
                      open(os.path.join(args.out, "interactive-sink.log")).read())
        if m:
            port = m.group(1)
            break
        time.sleep(0.05)
    if not port:
        sink.kill()
        sys.exit("interactive_bench: the sink did not start")
    mpirun = ["mpirun", "--oversubscribe", "--bind-to", "none", "-np", str(args.ranks)]
    if os.getuid() == 0:
        mpirun.append("--allow-run-as-root")
    render = subprocess.Popen(
        mpirun + [args.voxwall, "render", vwz, "--wall", args.wall, "--sink", "127.0.0.1:" + port,
                  "--path", "still", "--frames", "100000", "--interactive-step", str(args.step),
                  "--settle", "0.5"] + (["--shading"] if args.shading else []),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
    frames = []  # (ms, step)
    lines = queue.Queue()
    threading.Thread(target=lambda: [lines.put(l) for l in render.stdout] and None,
                     daemon=True).start()
    seen = []
    try:
        drag_until = None
        next_command = 0.0
        while True:
            try:
                line = lines.get(timeout=0.02)
                seen.append(line)
                m = LINE.match(line)
                if m:
                    step = re.search(r"interactive 1/(\d+)", line)
                    frames.append((float(m.group(2)), int(step.group(1)) if step else 1))
            except queue.Empty:
                if render.poll() is not None:
                    sys.exit("interactive_bench: the render job ended early:\n" +
                             "".join(seen[-10:]))
            full = [f for f in frames if f[1] == 1]
            if drag_until is None and len(full) >= args.full:
                drag_until = time.time() + args.drag_seconds
            if drag_until is not None:
                if time.time() > drag_until:
                    break
                if time.time() >= next_command:
                    sink.stdin.write("rotate 1 0\n")
                    sink.stdin.flush()
                    next_command = time.time() + 0.1
    finally:
        render.terminate()
        try:
            render.wait(timeout=30)
        except subprocess.TimeoutExpired:
            render.kill()
        sink.terminate()
        sink.wait(timeout=30)
    full = [ms for ms, step in frames if step == 1]
    drag = [ms for ms, step in frames if step > 1]
    if len(full) < 1 or len(drag) < 2:
        sys.exit(f"interactive_bench: measured {len(full)} full and {len(drag)} interactive "
                 "frames; need at least 1 and 2")
    wall = os.path.basename(args.wall)
    full_ms, drag_ms = statistics.mean(full), statistics.median(drag[1:])
    print(f"# {wall}, {args.ranks} ranks, {'shaded' if args.shading else 'unshaded'}; "
          f"one run: {len(full)} full frame(s), {len(drag)} interactive frame(s) at "
          f"1/{args.step} while a command came every 0.1 s")
    print("| frames | frame ms | frames/s |")
    print("|---|---|---|")
    print(f"| full resolution (mean) | {full_ms:.0f} | {1000 / full_ms:.2f} |")
    print(f"| while dragging, 1/{args.step} per side (median, first one excluded) | "
          f"{drag_ms:.0f} | {1000 / drag_ms:.2f} |")
    print(f"| ratio | | {full_ms / drag_ms:.1f}x |")


if __name__ == "__main__":
    main()
