#!/usr/bin/env python3
"""The main job's frames by default (the ray lattice, the step from the error budget) against a ray
a pixel at a quarter voxel (--exact), with each
frame's PSNR against the converged render of the same camera (a ray a pixel at a 1/8-voxel step).

The main job's set-up: the MRI template (Debian's mricron-data) compressed as run-main.sh does,
the bigeye wall's virtual screen, shaded, an orbit, on --ranks MPI ranks of --threads threads
each. Frames are rendered and written by rank 0 (PNG), then compared here; the frame times are
the slowest rank's render time as `voxwall render` prints them (writing runs in a background
thread and is not counted). Prints a table and exits non-zero when it cannot parse what it ran.

    /usr/bin/python3 bench/lattice_bench.py --voxwall build/master/voxwall [--frames 3] \
        [-- --refine-above 16]
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
FRAME_LINE = re.compile(r"^frame (\d+)/(\d+): ([\d.]+) ms, imbalance [\d.]+, render ms \[([^\]]*)\]")
RAYS_LINE = re.compile(r"^\s+(\d+) samples, (\d+) rays for (\d+) pixels \(ray lattice (\d+)")


def fail(why):
    print(f"lattice_bench: {why}", file=sys.stderr)
    sys.exit(1)


def mpirun(ranks):
    cmd = ["mpirun", "--oversubscribe", "--bind-to", "none", "-np", str(ranks)]
    if os.geteuid() == 0:
        cmd.append("--allow-run-as-root")
    return cmd


def render(args, vwz, out, extra):
    cmd = mpirun(args.ranks) + [args.voxwall, "render", vwz, "--wall", args.wall, "--frames",
                                str(args.frames), "--orbit-deg", str(args.orbit_deg), "--shading",
                                "--threads", str(args.threads), "--out", out, "-v"] + extra
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode != 0:
        fail(f"{' '.join(cmd)} failed:\n{run.stderr}")
    frames, rays = [], []
    for line in run.stdout.splitlines():
        m = FRAME_LINE.match(line)
        if m:
            frames.append(max(float(v.split(":")[1]) for v in m.group(4).split()) / 1e3)
        m = RAYS_LINE.match(line)
        if m:
            rays.append((int(m.group(2)), int(m.group(3)), int(m.group(4))))
    if len(frames) != args.frames or len(rays) != args.frames:
        fail(f"expected {args.frames} frame lines with rays, got {len(frames)} and {len(rays)}:\n"
             f"{run.stdout}")
    return frames, rays


def load(path):
    return load_rgba(path, "lattice_bench")


psnr = psnr8


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--voxwall", default="build/master/voxwall")
    p.add_argument("--wall", default="walls/bigeye.json")
    p.add_argument("--frames", type=int, default=3)
    p.add_argument("--orbit-deg", type=float, default=60)
    p.add_argument("--ranks", type=int, default=2)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--keep", help="keep the frames in this folder")
    p.add_argument("render", nargs="*", help="more options for the default run (after --)")
    args = p.parse_args()
    if not os.path.exists(MRI):
        fail(f"{MRI} is missing (apt-get install mricron-data)")
    work = args.keep or tempfile.mkdtemp(prefix="lattice-bench-")
    os.makedirs(work, exist_ok=True)
    vwz = os.path.join(work, "default.vwz")
    if not os.path.exists(vwz):
        subprocess.run([args.voxwall, "compress", MRI, "-o", vwz, "-q"], check=True)
    runs = {}
    for name, extra in [("exact", ["--exact"]), ("default", args.render),
                        ("converged", ["--exact", "--step", "0.125"])]:
        out = os.path.join(work, name)
        shutil.rmtree(out, ignore_errors=True)
        runs[name] = (out,) + render(args, vwz, out, extra)
    print(f"main job: {os.path.basename(MRI)}, {args.wall}, shaded, {args.ranks} ranks x "
          f"{args.threads} thread(s), orbit of {args.orbit_deg:g} degrees a frame")
    print("| frame | --exact render | default render | default / exact | rays cast (default) "
          "| lattice | PSNR default vs converged | PSNR --exact vs converged |")
    print("|---|---|---|---|---|---|---|---|")
    ratios, worst = [], 99.0
    for f in range(args.frames):
        name = f"frame_{f:05d}.png"
        ref = load(os.path.join(runs["converged"][0], name))
        d, e = (load(os.path.join(runs[k][0], name)) for k in ("default", "exact"))
        pd, pe = psnr(d, ref), psnr(e, ref)
        worst = min(worst, pd)
        te, td = runs["exact"][1][f], runs["default"][1][f]
        rays, pixels, stride = runs["default"][2][f]
        ratios.append(td / te)
        print(f"| {f + 1} | {te:.2f} s | {td:.2f} s | {td / te:.2f} | {rays / pixels:.1%} "
              f"| {stride} | {pd:.1f} dB | {pe:.1f} dB |")
    print(f"mean default / exact {np.mean(ratios):.2f}; worst default frame {worst:.1f} dB")
    if not args.keep:
        shutil.rmtree(work)


if __name__ == "__main__":
    main()
