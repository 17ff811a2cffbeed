"""What the browser tests share: failures, waiting on a condition with a deadline, PNG reading
and PSNR (plain Python: Debian's python3 with selenium needs nothing else), processes started in
their own session, and headless chromium through Selenium.
"""
import base64
import math
import os
import re
import signal
import struct
import subprocess
import sys
import time
import zlib

from selenium import webdriver
from selenium.webdriver.chrome.service import Service


class Failure(Exception):
    pass


def read_png(data):
    """8-bit RGB or RGBA, non-interlaced PNG bytes -> (width, height, rows of RGB bytes)."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise Failure("not a PNG")
    pos, idat, width = 8, b"", None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if depth != 8 or colour not in (2, 6) or interlace:
                raise Failure(f"PNG kind not handled (depth {depth}, colour {colour})")
            channels = 3 if colour == 2 else 4
        elif kind == b"IDAT":
            idat += body
    raw = zlib.decompress(idat)
    stride = width * channels
    rows, prev = [], bytearray(stride)
    for y in range(height):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b = prev[i]
            c = prev[i - channels] if i >= channels else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line))
        prev = line
    rgb = [bytes(r[i] for i in range(len(r)) if i % channels < 3) for r in rows]
    return width, height, rgb


def rgba_rows(got):
    """A page's {"rgba": base64 RGBA bytes, "width", "height"} -> rows of RGB bytes."""
    rgba = base64.b64decode(got["rgba"])
    w = got["width"]
    return [bytes(b for i, b in enumerate(rgba[y * 4 * w:(y + 1) * 4 * w]) if i % 4 < 3)
            for y in range(got["height"])]


def psnr(a, b):
    """PSNR in dB of two lists of RGB rows of equal size."""
    se = n = 0
    for ra, rb in zip(a, b):
        se += sum((x - y) ** 2 for x, y in zip(ra, rb))
        n += len(ra)
    return math.inf if se == 0 else 10 * math.log10(255 * 255 * n / se)


def sink_ports(sink_log):
    """The tile port and the page's address a `voxwall sink --http` on loopback printed to
    `sink_log`, once it has."""
    text = open(sink_log).read()
    tiles = re.search(r"listening on 127\.0\.0\.1:(\d+)", text)
    page = re.search(r"wall page at (http://127\.0\.0\.1:\d+/)", text)
    return (tiles.group(1), page.group(1)) if tiles and page else None


def page_frame(driver):
    """The newest frame the page drew: its metadata and its pixels as RGB rows."""
    got = driver.execute_script("""
        const s = window.voxwall;
        if (!s.bitmap || !s.meta) return null;
        const c = document.createElement('canvas');
        c.width = s.bitmap.width; c.height = s.bitmap.height;
        const g = c.getContext('2d');
        g.drawImage(s.bitmap, 0, 0);
        const px = g.getImageData(0, 0, c.width, c.height).data;
        let bin = '';
        for (let i = 0; i < px.length; i += 32768)
          bin += String.fromCharCode.apply(null, px.subarray(i, i + 32768));
        return {meta: s.meta, width: c.width, height: c.height, rgba: btoa(bin)};""")
    if not got:
        return None
    return got["meta"], rgba_rows(got)


def wait(what, condition, seconds):
    deadline = time.time() + seconds
    while time.time() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.1)
    raise Failure(f"timed out after {seconds} s waiting for {what}")


def sink_file(path, frame, sink_log, seconds=30):
    """Waits for the sink's file `path` of `frame`. Returns None when the sink's log (read by
    `sink_log()`) says it did not write that frame: its file writer skips the oldest frame it
    holds when it falls behind a fast stream, so a test picks a newer frame then."""
    skipped = re.compile(rf"^frame {frame} not written", re.M)

    def ready():
        if os.path.exists(path):
            return path
        return "skipped" if skipped.search(sink_log()) else None

    got = wait(f"the sink's file {os.path.basename(path)}", ready, seconds)
    return None if got == "skipped" else got


def chromium(work, name, window="1100,760"):
    """A headless chromium of its own (one browser per display host)."""
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage",
                 "--force-device-scale-factor=1", f"--window-size={window}",
                 f"--user-data-dir={os.path.join(work, 'chromium-' + name)}"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
    driver.set_script_timeout(30)
    return driver


class Processes:
    """Processes started in their own session, each logging to a file; all stopped at the end."""

    def __init__(self, work):
        self.work, self.procs = work, []

    def start(self, cmd, log):
        p = subprocess.Popen(cmd, stdout=open(os.path.join(self.work, log), "w"),
                             stderr=subprocess.STDOUT, cwd=self.work, start_new_session=True)
        self.procs.append(p)
        return p

    def stop(self, p):
        try:
            os.killpg(p.pid, signal.SIGTERM)
            p.wait(timeout=10)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass

    def stop_all(self):
        for p in reversed(self.procs):
            self.stop(p)

    def log(self, name):
        path = os.path.join(self.work, name)
        return open(path).read() if os.path.exists(path) else ""

    def fail(self, error, logs):
        """Says what failed and how the logs end, on stderr; returns the exit status 1."""
        print(f"FAIL: {error}", file=sys.stderr)
        for name in logs:
            if text := self.log(name):
                print(f"--- {name} (last lines)", file=sys.stderr)
                print("".join(text.splitlines(True)[-15:]), file=sys.stderr)
        return 1
