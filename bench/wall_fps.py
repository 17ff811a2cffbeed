#!/usr/bin/env python3
"""The wall's frame rate at the sink: a recorded bigeye frame stream (one MRI frame as 2 ranks cut
and compress it: JPEG segments at the display edges and every 1024 pixels) replayed into
`voxwall sink` as fast as it takes it, in these set-ups:

  - no output, nobody watching;
  - 12 display pages played by light WebSocket clients that answer at once (so the numbers are
    the sink's, not a browser's): frames presented and switched together per second, the sink's
    CPU per frame, bytes per display per frame;
  - --out (PNG, zlib level 1), --out --out-format jpg, --out --mosaic: frames written per second;
  - real headless chromium display pages (--chromium N of them): the spread of the times the
    pages showed each frame they switched to together (median and p95), from the sink's log.

Usage: /usr/bin/python3 bench/wall_fps.py [--voxwall BIN] [--replay BIN] [--frame PNG]
           [--frames N] [--chromium N] [--chromium-seconds S]
Prints markdown tables. Stops with an error when a run's output cannot be parsed.
"""
import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def fail(message):
    sys.exit(f"wall_fps: {message}")


def wait_for(what, condition, seconds):
    deadline = time.time() + seconds
    while time.time() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.05)
    fail(f"timed out after {seconds} s waiting for {what}")


class Sink:
    """`voxwall sink` on loopback; its CPU time comes from wait4 when it exits."""

    def __init__(self, args, work, extra, frames):
        self.log = os.path.join(work, f"sink-{time.time_ns()}.log")
        cmd = [args.voxwall, "sink", "--wall", args.wall, "--listen", "127.0.0.1:0",
               "--no-stdin", "--frames", str(frames), *extra]
        self.proc = subprocess.Popen(cmd, stdout=open(self.log, "w"), stderr=subprocess.STDOUT)
        self.port = int(wait_for("the sink to listen", lambda: self._match(
            r"listening on 127\.0\.0\.1:(\d+)"), 30))
        self.http = None
        if "--http" in extra:
            self.http = int(wait_for("the sink's pages", lambda: self._match(
                r"wall page at http://127\.0\.0\.1:(\d+)/"), 30))

    def _match(self, pattern):
        m = re.search(pattern, open(self.log).read())
        return m.group(1) if m else None

    def finish(self, seconds=120):
        """Waits for the sink to exit (it does after --frames); returns its CPU seconds."""
        deadline = time.time() + seconds
        while time.time() < deadline:
            pid, status, usage = os.wait4(self.proc.pid, os.WNOHANG)
            if pid:
                self.proc.returncode = os.waitstatus_to_exitcode(status)
                return usage.ru_utime + usage.ru_stime
            time.sleep(0.05)
        self.proc.terminate()
        fail(f"the sink did not exit within {seconds} s; its log: {self.log}")

    def text(self):
        return open(self.log).read()


def replay(args, sink, pages, frames, rate=0):
    cmd = [args.replay, "--wall", args.wall, "--frame", args.frame,
           "--sink", f"127.0.0.1:{sink.port}", "--frames", str(frames), "--ranks", "2",
           "--rate", str(rate)]
    if pages:
        cmd += ["--http", str(sink.http), "--pages", str(pages)]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    values = dict(re.findall(r"(\w+)=([0-9.]+)", out.stdout))
    needed = ["presented", "seconds", "presented_per_s", "frame_bytes", "segments"]
    if out.returncode != 0 or any(k not in values for k in needed):
        fail(f"the replay failed ({out.returncode}): {out.stderr.strip() or out.stdout.strip()}")
    return {k: float(v) for k, v in values.items()}


def writer_rate(folder):
    """Frames the sink's writer finished per second: between its first and last frame marker."""
    times = sorted(os.path.getmtime(os.path.join(folder, f)) for f in os.listdir(folder)
                   if f.endswith(".done"))
    if len(times) < 3:
        fail(f"only {len(times)} frames were written to {folder}")
    return (len(times) - 1) / max(times[-1] - times[0], 1e-9)


def sink_run(args, work, label, extra, pages=0, frames=None, out=None, rate=0):
    frames = frames or args.frames
    if out:
        extra = extra + ["--out", out]
    sink = Sink(args, work, extra, frames)
    start = time.time()
    r = replay(args, sink, pages, frames, rate)
    cpu = sink.finish()
    elapsed = time.time() - start
    if sink.proc.returncode != 0:
        fail(f"{label}: the sink exited with {sink.proc.returncode}: {sink.text()[-500:]}")
    m = re.search(r"sink: (\d+) frame\(s\) presented.*?(\d+) written, (\d+) not written.*?"
                  r"(\d+) switched together", sink.text(), re.S)
    if not m:
        fail(f"{label}: no summary line in the sink's log {sink.log}")
    presented, written, _, swapped = (int(g) for g in m.groups())
    return {"label": label, "frames": frames, "presented": presented,
            "presented_per_s": r["presented_per_s"], "seconds": r["seconds"],
            "cpu_per_frame_ms": 1000 * cpu / max(presented, 1),
            "cores": cpu / max(elapsed, 1e-9), "written": written,
            "written_per_s": writer_rate(out) if out else 0, "swapped": swapped,
            "swapped_per_s": swapped / max(r["seconds"], 1e-9),
            "bytes_per_display_frame": r.get("bytes_per_display_frame", 0),
            "frame_bytes": r["frame_bytes"], "segments": r["segments"]}


def chromium_skew(args, work):
    """Real display pages in headless chromium, one process each; the sink logs the spread."""
    chromium = shutil.which("chromium")
    if not chromium:
        fail("--chromium needs Debian's chromium")
    sink = Sink(args, work, ["--http", "127.0.0.1:0", "--swap-lead", str(args.swap_lead)], 100000)
    listing = json.load(urllib.request.urlopen(f"http://127.0.0.1:{sink.http}/displays.json"))
    names = [d["name"] for d in listing["displays"]][:args.chromium]
    browsers = []
    for name in names:
        profile = os.path.join(work, f"chromium-{name}")
        browsers.append(subprocess.Popen(
            [chromium, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
             "--disable-background-networking", "--disable-component-update",
             "--disable-background-timer-throttling", "--disable-renderer-backgrounding",
             "--disable-backgrounding-occluded-windows", "--window-size=1920,1080",
             "--force-device-scale-factor=1", f"--user-data-dir={profile}",
             f"http://127.0.0.1:{sink.http}/display/{name}"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
    try:
        wait_for("the chromium pages to connect", lambda: sink.text().count(
            "display page r") >= len(names), 60)
        # A stream at --chromium-rate: the barrier paces the pages, newest frame first.
        cmd = [args.replay, "--wall", args.wall, "--frame", args.frame,
               "--sink", f"127.0.0.1:{sink.port}", "--frames", "100000", "--ranks", "2",
               "--rate", str(args.chromium_rate)]
        feeder = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(args.chromium_seconds)
        feeder.kill()
        feeder.wait()
    finally:
        for b in browsers:
            b.kill()
            b.wait()
        sink.proc.terminate()
        sink.finish(30)
    spreads = [(int(n), float(s)) for n, s in re.findall(
        r"shown together on (\d+) display page\(s\), spread ([0-9.]+) ms", sink.text())]
    full = [s for n, s in spreads if n == len(names)]
    if len(full) < 5:
        tail = "".join(sink.text().splitlines(True)[-15:])
        fail(f"only {len(full)} frames were shown together on all {len(names)} chromium pages; "
             f"the sink's log ends:\n{tail}")
    full.sort()
    p95 = full[min(len(full) - 1, int(round(0.95 * (len(full) - 1))))]
    return {"pages": len(names), "frames": len(full), "median": statistics.median(full),
            "p95": p95, "max": full[-1], "per_s": len(full) / args.chromium_seconds,
            "rate": args.chromium_rate, "lead": args.swap_lead}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--voxwall", default=os.path.join(ROOT, "build/master/voxwall"))
    ap.add_argument("--replay", default=os.path.join(ROOT, "build/bench/voxwall_bench_wall_replay"))
    ap.add_argument("--wall", default=os.path.join(ROOT, "walls/bigeye.json"))
    ap.add_argument("--frame", help="a rendered frame of the wall (default: the MRI, rendered)")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--out-frames", type=int, default=40)
    ap.add_argument("--chromium", type=int, default=0, help="headless chromium pages (0: none)")
    ap.add_argument("--chromium-seconds", type=float, default=30)
    ap.add_argument("--chromium-rate", type=float, default=10,
                    help="frames per second streamed to the chromium pages")
    ap.add_argument("--swap-lead", type=int, default=25,
                    help="the sink's --swap-lead for the chromium run")
    ap.add_argument("--skip-sink-runs", action="store_true",
                    help="only the chromium run (with --chromium)")
    args = ap.parse_args()
    for tool in (args.voxwall, args.replay):
        if not os.access(tool, os.X_OK):
            fail(f"{tool} is missing: build first (bash scripts/build.sh)")
    work = tempfile.mkdtemp(prefix="voxwall-wall-fps.")
    try:
        if not args.frame:
            vwz = os.path.join(work, "mri.vwz")
            subprocess.run([args.voxwall, "compress",
                            "/usr/share/mricron/templates/ch2better.nii.gz", "-o", vwz, "-q"],
                           check=True)
            subprocess.run([args.voxwall, "render", vwz, "--wall", args.wall, "--shading",
                            "--out", os.path.join(work, "frame"), "-q"], check=True)
            args.frame = os.path.join(work, "frame", "frame_00000.png")
        print(f"machine: {os.cpu_count()} cores, {time.strftime('%Y-%m-%d')}; wall "
              f"{os.path.basename(args.wall)}; 2 ranks replayed at full speed")
        print()
        http = ["--http", "127.0.0.1:0"]
        runs = [] if args.skip_sink_runs else [sink_run(args, work, "no output, nobody watching", []),
                sink_run(args, work, "12 display pages, stream at full speed", http, pages=12),
                sink_run(args, work, "12 display pages, a 30 frames/s stream", http, pages=12,
                         rate=30),
                sink_run(args, work, "12 display pages, a 60 frames/s stream", http, pages=12,
                         rate=60)]
        out = os.path.join(work, "out")
        for label, extra in () if args.skip_sink_runs else (("--out (PNG)", []), ("--out --out-format jpg", ["--out-format", "jpg"]),
                             ("--out --mosaic (PNG)", ["--mosaic"])):
            shutil.rmtree(out, ignore_errors=True)
            runs.append(sink_run(args, work, label, extra, frames=args.out_frames, out=out))
        if runs:
            first = runs[0]
            print(f"The stream: {first['frame_bytes'] / 1024:.0f} KiB a frame in "
                  f"{first['segments']:.0f} segments.")
            print()
            print("| sink | frames presented | presented/s | switched together on all pages/s | "
                  "frames written/s | sink CPU per frame | sink cores busy | bytes per display "
                  "per frame |")
            print("|---|---|---|---|---|---|---|---|")
        for r in runs:
            cells = [r["label"], f"{r['presented']} of {r['frames']}",
                     f"{r['presented_per_s']:.1f}",
                     f"{r['swapped_per_s']:.1f}" if r["swapped"] else "-",
                     f"{r['written_per_s']:.2f}" if r["written_per_s"] else "-",
                     f"{r['cpu_per_frame_ms']:.1f} ms", f"{r['cores']:.2f}",
                     f"{r['bytes_per_display_frame'] / 1024:.1f} KiB"
                     if r["bytes_per_display_frame"] else "-"]
            print("| " + " | ".join(cells) + " |")
        if args.chromium:
            s = chromium_skew(args, work)
            print()
            print(f"Headless chromium display pages ({s['pages']}, one process each, a "
                  f"{s['rate']:.0f} frames/s stream for {args.chromium_seconds:.0f} s, "
                  f"--swap-lead {s['lead']}): "
                  f"{s['frames']} frames shown together on all pages ({s['per_s']:.1f}/s); "
                  f"show-time spread median {s['median']:.1f} ms, p95 {s['p95']:.1f} ms, "
                  f"max {s['max']:.1f} ms.")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
