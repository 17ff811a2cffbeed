#!/usr/bin/env python3
"""The wall page in a real browser: Debian's chromium, headless, driven by Selenium through
chromedriver, opens the page of a `voxwall sink --http` fed by a 2-rank render on loopback.

It checks that
  - the wall image is on the page (a screenshot of the canvas is not blank) and is the frame the
    sink presented (the page's picture against the sink's own mosaic file of that frame, PSNR);
  - a mouse drag on the canvas steers the job: interactive (reduced) frames come first, then a
    full frame from a moved camera (unlike the frame before the drag), again equal to what the
    sink presented;
  - touch works too: a one-finger drag sends a rotation, two fingers moving apart a zoom in.

Usage: wall_page_test.py --voxwall BIN --mpiexec MPIEXEC [--preflags "..."] --walls DIR
                         [--wall ci-2x2] [--volume FILE] [--screenshot PNG] [--overlay]
Exits 0 when every check passed; one line saying what failed and 1 otherwise.
"""
import argparse
import os
import shlex
import subprocess
import sys
import tempfile
import time

from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.actions.action_builder import ActionBuilder
from selenium.webdriver.common.by import By

from webtest import (Failure, Processes, chromium, page_frame, psnr, read_png, sink_file,
                     sink_ports, wait)


def check_against_sink(driver, wall_dir, sink_log, condition, what):
    """A frame the page drew (the newest one meeting `condition`) against the mosaic the sink
    wrote for the same frame id; a frame the sink's writer skipped is passed over for a newer
    one. Returns the frame's metadata, its rows and the PSNR."""
    skipped = -1
    for _ in range(10):
        meta, rows = wait(what, lambda: (f := page_frame(driver)) and condition(f[0]) and
                          f[0]["frame"] > skipped and f, 60)
        mosaic = sink_file(os.path.join(wall_dir, "frame_%05d_mosaic.png" % meta["frame"]),
                           meta["frame"], lambda: open(sink_log).read(), 20)
        if not mosaic:
            skipped = meta["frame"]
            continue
        w, h, ref = read_png(open(mosaic, "rb").read())
        if (w, h) != (meta["width"], meta["height"]):
            raise Failure(f"{what}: the page shows {meta['width']}x{meta['height']}, the sink "
                          f"presented {w}x{h}")
        value = psnr(rows, ref)
        if value < 30:
            raise Failure(f"{what}: the page's frame {meta['frame']} is {value:.1f} dB from the "
                          f"frame the sink presented (at least 30 expected)")
        return meta, rows, value
    raise Failure(f"{what}: the sink wrote none of 10 frames the page drew")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--voxwall", required=True)
    ap.add_argument("--mpiexec", required=True)
    ap.add_argument("--preflags", default="")
    ap.add_argument("--walls", required=True)
    ap.add_argument("--wall", default="ci-2x2")
    ap.add_argument("--volume", help="volume to render (default: a generated Shepp-Logan)")
    ap.add_argument("--screenshot", help="also save a screenshot of the page here")
    ap.add_argument("--overlay", action="store_true", help="turn the overlay on for the screenshot")
    ap.add_argument("--window", default="1100,760")
    args = ap.parse_args()
    args.voxwall, args.walls = os.path.abspath(args.voxwall), os.path.abspath(args.walls)
    if args.volume:
        args.volume = os.path.abspath(args.volume)

    work = tempfile.mkdtemp(prefix="voxwall-web.")
    procs = Processes(work)
    driver = None

    try:
        volume = args.volume
        if not volume:
            volume = os.path.join(work, "vol.vwz")
            subprocess.run([args.voxwall, "compress", "generated:shepp-logan:64", "-o", volume,
                            "-q"], check=True, timeout=120, stdout=subprocess.DEVNULL)
        wall = os.path.join(args.walls, args.wall + ".json")
        wall_dir = os.path.join(work, "wall")
        sink_log = os.path.join(work, "sink.log")
        procs.start([args.voxwall, "sink", "--wall", wall, "--listen", "127.0.0.1:0", "--http",
                     "127.0.0.1:0", "--out", wall_dir, "--mosaic", "--no-stdin"], "sink.log")

        tile_port, url = wait("the sink to listen", lambda: sink_ports(sink_log), 30)
        procs.start([args.mpiexec, *shlex.split(args.preflags), "-np", "2", args.voxwall,
                     "render", volume, "--wall", wall, "--sink", "127.0.0.1:" + tile_port,
                     "--frames", "100000", "--path", "still", "--threads", "1", "--settle", "1",
                     # A fixed step: under the default frame budget this small wall's full frames
                     # fit, and the page would see no reduced frame to show.
                     "--interactive-step", "4", "-q"], "render.log")

        driver = chromium(work, "wall", args.window)
        driver.get(url)
        state = lambda key: driver.execute_script(f"return window.voxwall.{key};")
        wait("frames on the page", lambda: (state("frames") or 0) >= 3, 120)

        # The wall is there: the canvas is not blank, and it is the frame the sink presented.
        canvas = driver.find_element(By.ID, "wall")
        w, h, shot = read_png(canvas.screenshot_as_png)
        lit = sum(1 for row in shot for i in range(0, len(row), 3)
                  if max(row[i:i + 3]) > 0x11 + 40)
        if lit < 0.02 * w * h:
            raise Failure(f"the page's wall looks blank: {lit} of {w * h} pixels lit")
        before_meta, before, before_db = check_against_sink(
            driver, wall_dir, sink_log, lambda m: m["step"] == 1, "a full frame before the drag")

        # A drag steers the job: interactive frames, then a settled frame from a moved camera.
        actions = ActionChains(driver)
        actions.move_to_element(canvas).click_and_hold()
        for _ in range(6):
            actions.move_by_offset(25, 4).pause(0.05)
        actions.release().perform()
        wait("the drag's commands", lambda: (state("commands") or 0) > 0, 10)
        wait("an interactive frame on the page", lambda: (state("reducedFrames") or 0) > 0, 60)
        last_reduced = state("lastReducedFrame")
        after_meta, after, after_db = check_against_sink(
            driver, wall_dir, sink_log, lambda m: m["step"] == 1 and m["frame"] > last_reduced,
            "a full frame after the drag")
        moved_db = psnr(before, after)
        if moved_db > 25:
            raise Failure(f"the frame after the drag is {moved_db:.1f} dB from the one before: "
                          "the camera did not move")
        if "interactive 1/" not in open(sink_log).read():
            raise Failure("the sink's log marks no frame as interactive")

        # Touch: one finger rotates, two fingers moving apart zoom in (pointer events).
        def touch(moves):
            builder = ActionBuilder(driver)
            fingers = [builder.add_pointer_input("touch", f"finger{i}") for i in range(len(moves))]
            for finger, (x0, x1) in zip(fingers, moves):
                finger.create_pointer_move(x=x0, y=0, origin=canvas, duration=0)
                finger.create_pointer_down(button=0)
                for k in range(1, 6):
                    finger.create_pointer_move(x=x0 + (x1 - x0) * k // 5, y=0, origin=canvas,
                                               duration=60)
                finger.create_pointer_up(button=0)
            builder.perform()

        def sent_since(count, word):
            lines = driver.execute_script("return window.voxwall.sent;")[-count:] if count else []
            return [line for line in lines if line.startswith(word)]

        before = state("commands")
        touch([(0, 120)])
        wait("a rotation from a one-finger drag", lambda: sent_since(
            state("commands") - before, "rotate"), 10)
        before = state("commands")
        touch([(-20, -140), (20, 140)])
        zooms = wait("a zoom from two fingers moving apart", lambda: sent_since(
            state("commands") - before, "zoom"), 10)
        if not any(float(z.split()[1]) > 1 for z in zooms):
            raise Failure(f"two fingers moving apart sent {zooms}, not a zoom in")

        if args.screenshot:
            if args.overlay:
                driver.find_element(By.ID, "overlay").click()
                time.sleep(1.0)
            driver.save_screenshot(args.screenshot)
        print(f"wall page: {state('frames')} frames drawn; frame {before_meta['frame']} "
              f"{before_db:.1f} dB and frame {after_meta['frame']} {after_db:.1f} dB against the "
              f"sink's; {state('reducedFrames')} interactive frame(s) during the drag; the frame "
              f"after it {moved_db:.1f} dB from the one before (moved); touch: rotate and {zooms[0]}")
        return 0
    except (Failure, subprocess.SubprocessError) as e:
        return procs.fail(e, ("sink.log", "render.log"))
    finally:
        if driver:
            driver.quit()
        procs.stop_all()
        subprocess.run(["rm", "-rf", work])

if __name__ == "__main__":
    sys.exit(main())
