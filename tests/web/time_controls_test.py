#!/usr/bin/env python3
"""The wall page's time controls in a real browser: Debian's chromium, headless, driven by
Selenium, opens the page of a `voxwall sink --http` fed by a 2-rank render of a generated time
series that plays by the clock (`render --time all --time-rate`).

It checks that
  - the page shows the time controls (they are hidden for a job of one volume) and the job plays:
    the step the page reports moves on by itself;
  - Pause holds the step: later frames keep it, and their pictures equal the paused one;
  - +1 and -1 move one step and the picture changes; the slider, moved with the keyboard (End,
    Home), seeks to the series' last and first steps; the space key plays again.

Usage: time_controls_test.py --voxwall BIN --mpiexec MPIEXEC [--preflags "..."] --walls DIR
                             [--wall ci-2x2]
Exits 0 when every check passed; one line saying what failed and 1 otherwise.
"""
import argparse
import os
import shlex
import subprocess
import sys
import tempfile

from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys

from webtest import Failure, Processes, chromium, page_frame, psnr, sink_ports, wait

STEPS = 6


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--voxwall", required=True)
    ap.add_argument("--mpiexec", required=True)
    ap.add_argument("--preflags", default="")
    ap.add_argument("--walls", required=True)
    ap.add_argument("--wall", default="ci-2x2")
    args = ap.parse_args()
    args.voxwall, args.walls = os.path.abspath(args.voxwall), os.path.abspath(args.walls)

    work = tempfile.mkdtemp(prefix="voxwall-time.")
    procs = Processes(work)
    driver = None
    try:
        series = os.path.join(work, "blobs.vwz")
        subprocess.run([args.voxwall, "generate", "blobs", "--steps", str(STEPS), "--size", "48",
                        "-o", series], check=True, timeout=120, stdout=subprocess.DEVNULL)
        wall = os.path.join(args.walls, args.wall + ".json")
        sink_log = os.path.join(work, "sink.log")
        procs.start([args.voxwall, "sink", "--wall", wall, "--listen", "127.0.0.1:0", "--http",
                     "127.0.0.1:0", "--no-stdin"], "sink.log")

        tile_port, url = wait("the sink to listen", lambda: sink_ports(sink_log), 30)
        # The browser first: a job playing a series renders without a pause, and chromium starts
        # slowly on a busy machine.
        driver = chromium(work, "time")
        driver.get(url)
        # Interactive reduction off (--interactive-step 1): every frame is a full one, so frames
        # of one step can be compared pixel for pixel. A frame of this series takes about 2 ms:
        # a job of 100000 frames ended in a CI run before a page slowed by a busy machine had
        # paused it, so the job lasts longer than the test's time limit.
        procs.start([args.mpiexec, *shlex.split(args.preflags), "-np", "2", args.voxwall,
                     "render", series, "--wall", wall, "--sink", "127.0.0.1:" + tile_port,
                     "--frames", "10000000", "--path", "still", "--threads", "1",
                     "--interactive-step", "1", "--time", "all", "--time-rate", "4", "-q"],
                    "render.log")

        script = lambda js: driver.execute_script("return " + js + ";")
        time_state = lambda: script("window.voxwall.time")
        wait("frames with the series' time on the page",
             lambda: (script("window.voxwall.frames") or 0) >= 3 and time_state(), 120)
        controls = driver.find_element(By.ID, "time")
        if not controls.is_displayed():
            raise Failure("the time controls are hidden while a series plays")
        t = time_state()
        if (t["first"], t["last"], t["stride"]) != (0, STEPS - 1, 1):
            raise Failure(f"the page says the series is {t}, not steps 0..{STEPS - 1}")

        # It plays by itself: the step moves without a command.
        first = t["step"]
        wait("the step to move on while playing", lambda: time_state()["step"] != first, 30)
        if script("window.voxwall.commands"):
            raise Failure("the page sent a command before it was touched")

        # Pause holds the step: the frames after it show one step, one picture.
        driver.find_element(By.ID, "timePlay").click()
        wait("the job to say it paused", lambda: not time_state()["playing"], 30)
        label = driver.find_element(By.ID, "timeLabel").text
        if "paused" not in label:
            raise Failure(f"the label reads {label!r} while paused")
        wait("a paused frame", lambda: (f := page_frame(driver)) and not f[0]["time"]["playing"],
             30)
        drawn = script("window.voxwall.frames")
        wait("more frames while paused", lambda: script("window.voxwall.frames") >= drawn + 4, 60)
        meta, paused = page_frame(driver)
        held = meta["time"]["step"]
        drawn = script("window.voxwall.frames")
        wait("more frames while paused", lambda: script("window.voxwall.frames") >= drawn + 4, 60)
        meta, later = page_frame(driver)
        if meta["time"]["step"] != held:
            raise Failure(f"paused at step {held}, the page shows step {meta['time']['step']} "
                          "later")
        same_db = psnr(paused, later)
        if same_db < 40:
            raise Failure(f"two frames of paused step {held} are {same_db:.1f} dB apart")

        # +1 and -1: one step each way, another picture.
        def step_to(button, want):
            driver.find_element(By.ID, button).click()
            got = wait(f"step {want} after {button}",
                       lambda: (f := page_frame(driver)) and f[0]["time"]["step"] == want and f,
                       30)
            if got[0]["time"]["playing"]:
                raise Failure(f"{button} started playing")
            return got[1]

        on = step_to("timeOn", (held + 1) % STEPS)
        moved_db = psnr(paused, on)
        if moved_db > 35:
            raise Failure(f"step {(held + 1) % STEPS} looks like step {held} ({moved_db:.1f} dB): "
                          "the picture did not change with the step")
        back = step_to("timeBack", held)
        back_db = psnr(paused, back)
        if back_db < 40:
            raise Failure(f"back at step {held}, the picture is {back_db:.1f} dB from before")

        # The slider with the keyboard: End seeks the last step, Home the first. A key that
        # leaves the slider where it is sends nothing, so the first key moves it: from the last
        # step, Home comes first.
        slider = driver.find_element(By.ID, "timeSlider")
        keys = [(Keys.END, STEPS - 1), (Keys.HOME, 0)]
        if held == STEPS - 1:
            keys.reverse()
        for key, want in keys:
            slider.send_keys(key)
            wait(f"the slider's seek to step {want}", lambda: time_state()["step"] == want, 30)
        seeks = [line for line in script("window.voxwall.sent") if line.startswith("seek")]
        expected = [f"seek {want}" for _, want in keys]
        if seeks[-2:] != expected:
            raise Failure(f"the slider sent {seeks}, not {' then '.join(expected)}")
        last_sought = keys[-1][1]

        # The space key plays again: the job says so and the step moves on.
        driver.find_element(By.ID, "wall").click()  # focus off the slider
        driver.find_element(By.TAG_NAME, "body").send_keys(" ")
        wait("the job to play again", lambda: time_state()["playing"], 30)
        wait("the step to move on again", lambda: time_state()["step"] != last_sought, 30)

        render_log = procs.log("render.log")
        if "error" in render_log.lower():
            raise Failure("the render job logged an error: " + render_log.strip()[-300:])
        print(f"time controls: played from step {first}; paused at step {held} (frames "
              f"{same_db:.1f} dB apart); +1 changed the picture ({moved_db:.1f} dB), -1 came "
              f"back ({back_db:.1f} dB); the slider sent {seeks[-2:]}; space played again")
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
