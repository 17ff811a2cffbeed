#!/usr/bin/env python3
"""The displays' pages in real browsers: a `voxwall sink --http` on the ci-2x2 wall fed by a
2-rank render on loopback, and one headless chromium per display (as one kiosk browser per
display host would be), each on /display/<name>.

It checks that
  - each page shows exactly its display of the frame the sink presented: the page's picture at
    the display's resolution equals the sink's own file of that display and frame (exactly with
    deflate tiles; >= 35 dB with JPEG tiles, from a second render job);
  - the pages switch together: between the first and the last frame all of them showed, each
    showed the same frames, the same frame id at each swap;
  - a page closed mid-run does not stop the other three from switching frames, and the sink
    names it; reopened, it shows frames again and is back in the barrier;
  - all of it with a token: the sink and the ranks are given one, the pages take it from their
    address's #token= fragment.

Usage: display_pages_test.py --voxwall BIN --mpiexec MPIEXEC [--preflags "..."] --walls DIR
Exits 0 when every check passed; one line saying what failed and 1 otherwise.
"""
import argparse
import os
import re
import shlex
import subprocess
import sys
import tempfile

from webtest import (Failure, Processes, chromium, psnr, read_png, rgba_rows, sink_file,
                     wait)


def page_picture(driver):
    """The page's front frame at the display's resolution: its metadata and RGB rows."""
    got = driver.execute_script("return window.voxwall.pixels();")
    if not got:
        return None
    return got, rgba_rows(got)


def history(driver):
    return driver.execute_script("return window.voxwall.history;") or []


def check_pictures(pages, wall_dir, sink_log, exact, what):
    """Each page's picture against the sink's file of its display for the same frame (a frame
    the sink's writer skipped is passed over for a newer one: on a loaded 2-core machine the
    writer skipped more than 10 frames in a row of an unthrottled stream, so up to 40 are tried)."""
    results = []
    for name, driver in pages.items():
        skipped, path = -1, None
        for _ in range(40):
            meta, rows = wait(f"a frame on page {name}",
                              lambda: (f := page_picture(driver)) and f[0]["frame"] > skipped
                              and f, 60)
            path = sink_file(os.path.join(wall_dir, "frame_%05d_%s.png" % (meta["frame"], name)),
                             meta["frame"], sink_log, 30)
            if path:
                break
            skipped = meta["frame"]
        if not path:
            raise Failure(f"{what}: the sink wrote none of 40 frames page {name} showed")
        w, h, ref = read_png(open(path, "rb").read())
        if (w, h) != (meta["width"], meta["height"]):
            raise Failure(f"{what}: page {name} shows {meta['width']}x{meta['height']}, the "
                          f"display is {w}x{h}")
        value = psnr(rows, ref)
        if exact and value != float("inf"):
            raise Failure(f"{what}: page {name}'s frame {meta['frame']} differs from the sink's "
                          f"file ({value:.1f} dB; deflate tiles must be exact)")
        if not exact and value < 35:
            raise Failure(f"{what}: page {name}'s frame {meta['frame']} is {value:.1f} dB from "
                          "the sink's file (at least 35 expected)")
        results.append(value)
    return results


def shown_after(pages, names, after):
    return {n: [(h["seq"], h["frame"]) for h in history(pages[n]) if h["seq"] > after]
            for n in names}


def common_frames(pages, names, after=-1):
    """The (swap, frame) pairs every page of `names` showed after swap `after`."""
    return set.intersection(*(set(s) for s in shown_after(pages, names, after).values()))


def check_together(pages, names, sink_log, after=-1):
    """The pages `names` switched together: once they have shown three frames in common after
    swap `after` (waited for: a busy machine delays a page), between the first and the last
    frame they all showed each showed the same frames (the same frame id at each swap) and none
    showed one the others did not. The swap timeout is long here, but a page the machine starves
    can still leave the barrier as slower than the others (the sink says so, and it is shown
    frames alone until it keeps up): then the check starts again once it is back, at most three
    times. Pages that differ while no page left fail at once."""
    for _ in range(3):
        left, joined = (sink_log().count(s) for s in ("left the swap barrier",
                                                       "is in the swap barrier"))
        try:
            wait(f"three frames shown together on all of {names}",
                 lambda: len(common_frames(pages, names, after)) >= 3, 120)
        except Failure:
            pass  # said below, with the count
        shown = shown_after(pages, names, after)
        common = set.intersection(*(set(s) for s in shown.values()))
        if len(common) < 3:
            raise Failure(f"only {len(common)} frames were shown on all of {names}")
        first, last = min(common), max(common)
        spans = {n: [x for x in shown[n] if first <= x <= last] for n in names}
        apart = [n for n in names[1:] if spans[n] != spans[names[0]]]
        if not apart:
            return len(common)
        if sink_log().count("left the swap barrier") == left:
            raise Failure(f"pages {names[0]} and {apart[0]} did not switch together: "
                          f"{spans[names[0]][:8]} against {spans[apart[0]][:8]} (seq, frame)")
        wait("the page that left the swap barrier to rejoin it",
             lambda: sink_log().count("is in the swap barrier") > joined, 120)
        after = max(h["seq"] for n in names for h in history(pages[n]))
    raise Failure(f"a page of {names} left the swap barrier in each of three checks")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--voxwall", required=True)
    ap.add_argument("--mpiexec", required=True)
    ap.add_argument("--preflags", default="")
    ap.add_argument("--walls", required=True)
    args = ap.parse_args()
    args.voxwall, args.walls = os.path.abspath(args.voxwall), os.path.abspath(args.walls)

    work = tempfile.mkdtemp(prefix="voxwall-displays.")
    procs = Processes(work)
    pages = {}
    try:
        volume = os.path.join(work, "vol.vwz")
        subprocess.run([args.voxwall, "compress", "generated:shepp-logan:64", "-o", volume, "-q"],
                       check=True, timeout=120, stdout=subprocess.DEVNULL)
        wall = os.path.join(args.walls, "ci-2x2.json")
        wall_dir = os.path.join(work, "wall")
        # A long swap timeout: a browser stalled by a busy machine should not leave the barrier
        # here (leaving and rejoining is the unit tests' business; check_together copes with a
        # page the slowness rule takes out); a closed page leaves at once.
        # With a token: the pages take it from their address's #token= and are told nothing
        # about the wall before they send it.
        token = "wall-s3cret"
        procs.start([args.voxwall, "sink", "--wall", wall, "--listen", "127.0.0.1:0", "--http",
                     "127.0.0.1:0", "--out", wall_dir, "--swap-timeout", "5000", "--no-stdin",
                     "--token", token], "sink.log")

        def sink_ports():
            text = procs.log("sink.log")
            tiles = re.search(r"listening on 127\.0\.0\.1:(\d+)", text)
            page = re.search(r"wall page at (http://127\.0\.0\.1:\d+)/", text)
            return (tiles.group(1), page.group(1)) if tiles and page else None

        tile_port, base = wait("the sink to listen", sink_ports, 30)
        sink_log = lambda: procs.log("sink.log")  # noqa: E731

        def render(codec, log):
            return procs.start([args.mpiexec, *shlex.split(args.preflags), "-np", "2",
                                args.voxwall, "render", volume, "--wall", wall, "--sink",
                                "127.0.0.1:" + tile_port, "--frames", "100000", "--orbit-deg",
                                "3", "--threads", "1", "--tile-codec", codec, "--token", token,
                                "-q"], log)

        names = ["r0c0", "r0c1", "r1c0", "r1c1"]

        def open_page(name):
            driver = chromium(work, name, "320,240")
            driver.get(f"{base}/display/{name}#token={token}")
            pages[name] = driver
            return driver

        for name in names:
            open_page(name)
        job = render("deflate", "render-deflate.log")
        for name in names:
            wait(f"frames on page {name}", lambda: len(history(pages[name])) >= 5, 120)
        exact = check_pictures(pages, wall_dir, sink_log, True, "deflate tiles")
        together = check_together(pages, names, sink_log)

        # One page goes; the other three keep switching frames without it.
        gone = names[3]
        pages.pop(gone).quit()
        wait("the sink to see the page go", lambda: re.search(
            rf"display page {gone} .* left", procs.log("sink.log")), 30)
        rest = names[:3]
        marks = {n: history(pages[n])[-1]["seq"] for n in rest}
        for n in rest:
            wait(f"page {n} to switch frames without {gone}",
                 lambda: history(pages[n])[-1]["seq"] >= marks[n] + 3, 60)
        check_together(pages, rest, sink_log)

        # Reopened, it shows frames again and is back in the barrier: from then on it switches
        # with the others (before, it is shown frames alone as it catches up).
        open_page(gone)
        wait(f"page {gone} back in the barrier", lambda: len(re.findall(
            rf"display page {gone} .* is in the swap barrier", procs.log("sink.log"))) >= 2, 60)
        back = max(h["seq"] for n in names for h in history(pages[n]))
        for n in names:
            wait(f"page {n} to switch frames with {gone} back",
                 lambda: history(pages[n])[-1]["seq"] >= back + 3, 60)
        rejoined = check_together(pages, names, sink_log, back)

        # JPEG tiles from a second job: the same pages, close to the sink's pictures.
        procs.stop(job)
        render("jpeg", "render-jpeg.log")
        wait("the JPEG job on the wall", lambda: "took the wall" in procs.log("sink.log"), 60)
        mark = {n: history(pages[n])[-1]["seq"] for n in names}
        for n in names:
            wait(f"JPEG frames on page {n}", lambda: history(pages[n])[-1]["seq"] >= mark[n] + 3,
                 120)
        jpeg = check_pictures(pages, wall_dir, sink_log, False, "JPEG tiles")
        print(f"display pages: 4 pages equal the sink's files with deflate tiles "
              f"({len(exact)} exact), {together} frames shown together on all four; three went "
              f"on without the fourth, which rejoined ({rejoined} frames together); JPEG tiles "
              f"{min(jpeg):.1f}-{max(jpeg):.1f} dB against the sink's files; a page left the "
              f"swap barrier {sink_log().count('left the swap barrier')} time(s)")
        return 0
    except (Failure, subprocess.SubprocessError) as e:
        return procs.fail(e, ("sink.log", "render-deflate.log", "render-jpeg.log"))
    finally:
        for driver in pages.values():
            driver.quit()
        procs.stop_all()
        subprocess.run(["rm", "-rf", work])


if __name__ == "__main__":
    sys.exit(main())
