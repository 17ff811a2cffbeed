#!/usr/bin/env python3
"""What each march along the ray costs and how far its picture is from the converged render, on
one view: the step (1/8 to 1 voxel), at points or pre-integrated, a ray a pixel, and the default
(the step picked from the error budget, the ray lattice), in one run.

The set-up: the MRI template (Debian's mricron-data, held raw), 2886x2169 (half the bigeye wall a
side), shaded, one rank of --threads threads, a still view (azimuth 30, elevation 20): each
setting renders two frames and the second one's render time is kept (the first plans the frame
and warms the caches). PSNR is over the four 8-bit channels against the converged render (a ray
a pixel at a 1/8-voxel step). Prints a markdown table; exits non-zero when it cannot parse what
it ran.

    /usr/bin/python3 bench/march_bench.py --voxwall build/master/voxwall [--unshaded]
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile

import numpy as np

from frames_common import load_rgba, psnr8

MRI = "/usr/share/mricron/templates/ch2better.nii.gz"
FRAME_LINE = re.compile(r"^frame (\d+)/(\d+): .*?render ms \[([^\]]*)\]")
STEP_LINE = re.compile(r"^\s+(\d+) samples, (\d+) rays for (\d+) pixels \(ray lattice (\d+).*step "
                       r"([\d.]+) voxels(, pre-integrated)?")
SETTINGS = [
    ("1/8 voxel (converged)", ["--exact", "--step", "0.125"]),
    ("1/4 voxel (`--exact`)", ["--exact"]),
    ("1/2 voxel, points", ["--step", "0.5", "--lattice", "1"]),
    ("1/2 voxel, pre-integrated", ["--step", "0.5", "--lattice", "1", "--integration", "pre"]),
    ("1 voxel, points", ["--step", "1", "--lattice", "1"]),
    ("1 voxel, pre-integrated", ["--step", "1", "--lattice", "1", "--integration", "pre"]),
    ("1/4 voxel, a lattice of 2 forced", ["--step", "0.25", "--lattice", "2"]),
    ("default (error budget, ray lattice)", []),
]


def fail(why):
    print(f"march_bench: {why}", file=sys.stderr)
    sys.exit(1)


def render(args, vwz, out, extra):
    cmd = [args.voxwall, "render", vwz, "--size", args.size, "--camera", "30,20,2.6",
           "--path", "still", "--frames", "2", "--threads", str(args.threads), "--out", out,
           "-v"] + ([] if args.unshaded else ["--shading"]) + extra
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode != 0:
        fail(f"{' '.join(cmd)} failed:\n{run.stderr}")
    times = [max(float(v.split(":")[1]) for v in m.group(3).split()) / 1e3
             for m in map(FRAME_LINE.match, run.stdout.splitlines()) if m]
    steps = [m for m in map(STEP_LINE.match, run.stdout.splitlines()) if m]
    if len(times) != 2 or len(steps) != 2:
        fail(f"expected 2 frame lines with their step, got {len(times)} and {len(steps)}:\n"
             f"{run.stdout}")
    s = steps[1]
    march = f"{float(s.group(5)):g}" + (" pre" if s.group(6) else "")
    return times[1], int(s.group(1)), int(s.group(2)) / int(s.group(3)), int(s.group(4)), march


def load(path):
    return load_rgba(path, "march_bench")


psnr = psnr8


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--voxwall", default="build/master/voxwall")
    p.add_argument("--size", default="2886x2169")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--unshaded", action="store_true")
    args = p.parse_args()
    if not os.path.exists(MRI):
        fail(f"{MRI} is missing (apt-get install mricron-data)")
    work = tempfile.mkdtemp(prefix="march-bench-")
    try:
        vwz = os.path.join(work, "mri.vwz")
        subprocess.run([args.voxwall, "compress", MRI, "-o", vwz, "-q"], check=True)
        rows = []
        for name, extra in SETTINGS:
            out = os.path.join(work, str(len(rows)))
            rows.append((name, out) + render(args, vwz, out, extra))
        ref = load(os.path.join(rows[0][1], "frame_00001.png"))
        exact_time = rows[1][2]
        print(f"MRI template, {args.size}, {'unshaded' if args.unshaded else 'shaded'}, one rank "
              f"x {args.threads} threads, the second frame of a still view")
        print("| setting | march | render | / `--exact` | samples | rays cast | PSNR vs converged |")
        print("|---|---|---|---|---|---|---|")
        for name, out, seconds, samples, rays, stride, march in rows:
            quality = psnr(load(os.path.join(out, "frame_00001.png")), ref)
            shown = "reference" if out == rows[0][1] else f"{quality:.1f} dB"
            print(f"| {name} | {march} | {seconds:.2f} s | {seconds / exact_time:.2f} | "
                  f"{samples / 1e6:.0f} M | {rays:.0%} (lattice {stride}) | {shown} |")
    finally:
        shutil.rmtree(work)


if __name__ == "__main__":
    main()
