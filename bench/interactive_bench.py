#!/usr/bin/env python3
"""Steering the wall, in one run: how fast the wall answers a camera command, and the frame rate
while steering against the full-resolution rate.

Starts `voxwall sink` for the wall with camera commands on its stdin, renders the volume on N MPI
ranks streaming to it with `--path still`, and reads both programs' lines as they come (each
stamped with this script's clock):

  --latency K (default 10): K times, once the wall shows a settled full-resolution frame, types
      one `rotate` command at a random moment of the next full frame in flight, and measures the
      time from the command to the first frame with the new camera presented by the sink, and to
      the next full-resolution frame presented after it;
  --drag-seconds S (default 0: off): types a `rotate` every 0.1 s (what a drag in the page
      sends) for S seconds and compares the steered frames' times with the full frames'.
  --page: the --latency commands are drags of a pointer on the sink's overview page in headless
      chromium (Debian's chromium, chromedriver and python3-selenium) instead of lines on the
      sink's stdin; the page also times, in its own clock, its first pointer event to the first
      refresh that shows an interactive frame.

Works with builds before the frame in flight could be abandoned too (the command then waits for
it), so the same script measures before and after.

Usage: interactive_bench.py [--voxwall BIN] [--wall walls/bigeye.json] [--volume FILE]
           [--ranks 2] [--latency 10] [--drag-seconds 20] [--page] [--shading]
           [-- RENDER OPTIONS...]
Prints tables; stops with an error when it cannot parse what it measured.
"""
import argparse
import os
import queue
import random
import re
import statistics
import subprocess
import sys
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RENDER_LINE = re.compile(r"^frame (\d+)/\d+: ([0-9.]+) ms, .*?-> sink: ")
PRESENTED = re.compile(r"^frame (\d+) presented: ")


def fail(message):
    sys.exit(f"interactive_bench: {message}")


class Lines:
    """A process's output lines, each with the time it was read."""

    def __init__(self, stream):
        self.queue = queue.Queue()
        threading.Thread(target=self._read, args=(stream,), daemon=True).start()

    def _read(self, stream):
        for line in stream:
            self.queue.put((time.monotonic(), line))

    def get(self, timeout):
        try:
            return self.queue.get(timeout=timeout)
        except queue.Empty:
            return None


class Wall:
    """The sink and the render job, and what both printed so far."""

    def __init__(self, args, extra):
        self.sink = subprocess.Popen([args.voxwall, "sink", "--wall", args.wall, "--listen",
                                      "127.0.0.1:0"] +
                                     (["--http", "127.0.0.1:0"] if args.page else []),
                                     stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     bufsize=1)
        self.sink_lines = Lines(self.sink.stdout)
        port, self.page_url = None, None
        deadline = time.monotonic() + 30
        while (port is None or (args.page and not self.page_url)) and time.monotonic() < deadline:
            got = self.sink_lines.get(0.1)
            if got and (m := re.search(r"listening on 127\.0\.0\.1:(\d+)", got[1])):
                port = m.group(1)
            if got and (m := re.search(r"wall page at (http://127\.0\.0\.1:\d+/)", got[1])):
                self.page_url = m.group(1)
        if not port or (args.page and not self.page_url):
            self.sink.kill()
            fail("the sink did not start")
        mpirun = ["mpirun", "--oversubscribe", "--bind-to", "none", "-np", str(args.ranks)]
        if os.getuid() == 0:
            mpirun.append("--allow-run-as-root")
        self.render = subprocess.Popen(
            mpirun + [args.voxwall, "render", args.vwz, "--wall", args.wall, "--sink",
                      "127.0.0.1:" + port, "--path", "still", "--frames", "1000000"] +
            (["--shading"] if args.shading else []) + extra,
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
        self.render_lines = Lines(self.render.stdout)
        self.frames = {}     # frame id -> (time read, ms, step, moved, abandoned)
        self.presented = {}  # frame id -> time read
        self.tail = []

    def pump(self, timeout=0.02):
        """Takes what both programs printed; fails when the render job ended."""
        got_any = False
        for source in (self.render_lines, self.sink_lines):
            while (got := source.get(timeout if not got_any else 0)) is not None:
                got_any = True
                t, line = got
                self.tail = (self.tail + [line])[-12:]
                if source is self.render_lines and (m := RENDER_LINE.match(line)):
                    step = re.search(r"(?:interactive|refining) 1/(\d+)", line)
                    self.frames[int(m.group(1)) - 1] = (
                        t, float(m.group(2)), int(step.group(1)) if step else 1,
                        "camera moved from the wall" in line, "abandoned" in line)
                elif source is self.sink_lines and (m := PRESENTED.match(line)):
                    self.presented[int(m.group(1))] = t
        if self.render.poll() is not None:
            fail("the render job ended early:\n" + "".join(self.tail))

    def wait(self, what, condition, seconds):
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.pump()
            if (value := condition()) is not None:
                return value
        fail(f"timed out after {seconds:.0f} s waiting for {what}:\n" + "".join(self.tail))

    def command(self, text):
        self.sink.stdin.write(text + "\n")
        self.sink.stdin.flush()
        return time.monotonic()

    def close(self):
        self.render.terminate()
        try:
            self.render.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.render.kill()
        self.sink.terminate()
        self.sink.wait(timeout=30)

    def full_frames(self, after=-1):
        """Full-resolution frames (not abandoned, no command in them) after frame `after`, shown."""
        return [f for f, (t, ms, step, moved, abandoned) in sorted(self.frames.items())
                if f > after and step == 1 and not moved and not abandoned
                and f in self.presented]


# Injected into the overview page: its first pointer event of a drag, and the first display
# refresh after it that shows a steered frame (interactive, or refining when the page skipped the
# interactive one; a build without phases: a reduced step).
PAGE_TIMER = """
const b = window.voxwallBench = {t0: null, t1: null};
const canvas = document.getElementById("wall");
const down = () => { if (b.t0 === null) b.t0 = performance.now(); };
canvas.addEventListener("pointerdown", down, {capture: true, once: true});
const seen = window.voxwall.frames;
(function tick() {
  const m = window.voxwall.meta;
  if (b.t0 !== null && window.voxwall.frames > seen && m &&
      (m.phase === "interactive" || m.phase === "refining" || (!m.phase && m.step > 1))) {
    b.t1 = performance.now();
    return;
  }
  requestAnimationFrame(tick);
})();
"""


class Page:
    """The sink's overview page in headless chromium; commands are drags on its canvas."""

    def __init__(self, url, work):
        try:
            from selenium import webdriver
            from selenium.webdriver.chrome.service import Service
        except ImportError:
            fail("--page needs python3-selenium, chromium and chromium-driver")
        options = webdriver.ChromeOptions()
        options.binary_location = "/usr/bin/chromium"
        for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
                     "--disable-background-networking", "--disable-component-update",
                     "--disable-background-timer-throttling", "--disable-dev-shm-usage",
                     "--force-device-scale-factor=1", "--window-size=1100,760",
                     f"--user-data-dir={os.path.join(work, 'chromium-bench')}"):
            options.add_argument(flag)
        self.driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
        self.driver.get(url)
        deadline = time.monotonic() + 120
        while not self.driver.execute_script("return window.voxwall && window.voxwall.frames"):
            if time.monotonic() > deadline:
                fail("the overview page showed no frame in 120 s")
            time.sleep(0.2)
        self.page_ms = []

    def command(self, _text):
        from selenium.webdriver.common.action_chains import ActionChains
        from selenium.webdriver.common.by import By
        self.driver.execute_script(PAGE_TIMER)
        canvas = self.driver.find_element(By.ID, "wall")
        sent = time.monotonic()
        ActionChains(self.driver).move_to_element(canvas).click_and_hold() \
            .move_by_offset(20, 0).release().perform()
        return sent

    def took(self):
        """The page's own time from the pointer to the picture, once it showed it."""
        got = self.driver.execute_script(
            "const b = window.voxwallBench; return b.t1 === null ? null : b.t1 - b.t0;")
        if got is not None:
            self.page_ms.append(got)
        return got

    def close(self):
        self.driver.quit()


def latency(wall, count, rng, page=None):
    """Command -> first frame with the new camera presented, and -> full resolution again."""
    first, full, abandoned = [], [], 0
    # Where the first answer's time goes: the frame in flight (until rank 0 printed it, abandoned
    # or whole), the new-camera frame's own render, and the rest (tiles to the sink, assembly).
    parts = {"in flight": [], "render": [], "rest": []}
    for i in range(count):
        # The wall shows a settled full frame: the next one is in flight.
        shown = wall.wait("a settled full frame",
                          lambda: f[-1] if (f := wall.full_frames()) else None, 600)
        full_s = wall.frames[shown][1] / 1000
        target = time.monotonic() + rng.uniform(0.05, 0.9) * full_s
        while time.monotonic() < target:
            wall.pump(min(0.02, max(0.0, target - time.monotonic())))
        sent = (page or wall).command(f"rotate {5 + i} 0")
        moved = wall.wait("the frame that took the command", lambda: next(
            (f for f, v in sorted(wall.frames.items()) if f > shown and v[3]), None), 600)
        took = wall.wait(f"frame {moved} on the wall", lambda: wall.presented.get(moved), 600)
        if page:
            wall.wait("the page to show it", page.took, 60)
        settled = wall.wait("full resolution again",
                            lambda: wall.presented[f[0]] if (f := wall.full_frames(moved)) else None,
                            600)
        abandoned += sum(1 for f, v in wall.frames.items() if shown < f < moved and v[4])
        before = [v[0] for f, v in wall.frames.items() if shown < f < moved and v[0] >= sent]
        in_flight = (max(before) - sent) if before else 0.0
        render = wall.frames[moved][1] / 1000
        parts["in flight"].append(in_flight)
        parts["render"].append(render)
        parts["rest"].append(max(0.0, took - sent - in_flight - render))
        first.append(took - sent)
        full.append(settled - sent)
    return first, full, abandoned, parts


def drag(wall, seconds):
    """A rotate every 0.1 s for `seconds`: the steered frames against the full ones before."""
    wall.wait("two full frames", lambda: len(wall.full_frames()) >= 2 or None, 600)
    before = max(wall.frames)
    end = time.monotonic() + seconds
    next_command = 0.0
    while time.monotonic() < end:
        if time.monotonic() >= next_command:
            wall.command("rotate 1 0")
            next_command = time.monotonic() + 0.1
        wall.pump()
    full = [wall.frames[f][1] for f in wall.full_frames() if f <= before]
    steered = [v[1] for f, v in sorted(wall.frames.items()) if f > before and v[2] > 1]
    steps = sorted({v[2] for f, v in wall.frames.items() if f > before and v[2] > 1})
    return full, steered, steps


def percentile(values, p):
    values = sorted(values)
    return values[min(len(values) - 1, int(round(p * (len(values) - 1))))]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--voxwall", default=os.path.join(ROOT, "build/master/voxwall"))
    ap.add_argument("--wall", default=os.path.join(ROOT, "walls/bigeye.json"))
    ap.add_argument("--volume", default="/usr/share/mricron/templates/ch2better.nii.gz")
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--latency", type=int, default=10, help="commands to time (0: none)")
    ap.add_argument("--drag-seconds", type=float, default=0)
    ap.add_argument("--shading", action="store_true")
    ap.add_argument("--page", action="store_true",
                    help="drag on the overview page in headless chromium instead of typing")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", default=os.path.join(ROOT, "bench-out"))
    ap.add_argument("render", nargs="*", help="more options for `voxwall render` (after --)")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    args.vwz = os.path.join(args.out, "interactive.vwz")
    subprocess.run([args.voxwall, "compress", args.volume, "-o", args.vwz, "-q"], check=True,
                   stdout=subprocess.DEVNULL)
    wall = Wall(args, args.render)
    page = None
    name = (f"{os.path.basename(args.wall)}, {args.ranks} ranks, "
            f"{'shaded' if args.shading else 'unshaded'}"
            f"{', ' + ' '.join(args.render) if args.render else ''}")
    try:
        if args.page:
            page = Page(wall.page_url, args.out)
        if args.latency > 0:
            first, full, abandoned, parts = latency(wall, args.latency, random.Random(args.seed),
                                                    page)
            how = "drags on the overview page" if page else "commands"
            print(f"# {name}: {len(first)} {how}, each at a random moment of a full frame "
                  f"in flight; {abandoned} frame(s) abandoned")
            print("| from the command to | median s | p95 s | max s |")
            print("|---|---|---|---|")
            rows = [("the first frame with the new camera on the wall", first),
                    ("full resolution on the wall again", full)]
            if page:
                rows.append(("the page's picture (pointer event to refresh, page clock)",
                             [ms / 1000 for ms in page.page_ms]))
            rows += [("  of the first: the frame in flight ends", parts["in flight"]),
                     ("  of the first: its own render", parts["render"]),
                     ("  of the first: the rest (tiles, assembly)", parts["rest"])]
            for label, values in rows:
                print(f"| {label} | {statistics.median(values):.2f} | "
                      f"{percentile(values, 0.95):.2f} | {max(values):.2f} |")
        if args.drag_seconds > 0:
            full, steered, steps = drag(wall, args.drag_seconds)
            if len(full) < 1 or len(steered) < 2:
                fail(f"measured {len(full)} full and {len(steered)} steered frames; need at "
                     "least 1 and 2")
            full_ms, steered_ms = statistics.mean(full), statistics.median(steered[1:])
            print(f"# {name}: a command every 0.1 s for {args.drag_seconds:.0f} s; "
                  f"{len(steered)} steered frame(s) at step(s) {steps}")
            print("| frames | frame ms | frames/s |")
            print("|---|---|---|")
            print(f"| full resolution (mean) | {full_ms:.0f} | {1000 / full_ms:.2f} |")
            print(f"| while dragging (median, first one excluded) | {steered_ms:.0f} | "
                  f"{1000 / steered_ms:.2f} |")
            p95_ms = percentile(steered[1:], 0.95)
            print(f"| while dragging (p95, first one excluded) | {p95_ms:.0f} | "
                  f"{1000 / p95_ms:.2f} |")
            print(f"| ratio | | {full_ms / steered_ms:.1f}x |")
    finally:
        if page:
            page.close()
        wall.close()


if __name__ == "__main__":
    main()
