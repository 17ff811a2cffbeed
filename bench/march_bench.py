#!/usr/bin/env python3
"""What each march along the ray costs and how far its picture is from the converged render, on
one view: the step (1/8 to 1 voxel), at points or pre-integrated, a ray a pixel, and the default
(the step picked from the error budget, the ray lattice), in one run.

The set-up: the MRI template (Debian's mricron-data, held raw; or, with --volume ct-phantom, the
3D Shepp-Logan head phantom as CT numbers: `voxwall generate shepp-logan --type int16`), 2886x2169 (half the bigeye wall a
side), shaded, one rank of --threads threads, a still view (azimuth 30, elevation 20): each
setting renders two frames and the second one's render time is kept (the first plans the frame
and warms the caches). PSNR is over the four 8-bit channels against the converged render (a ray
a pixel at a 1/8-voxel step). Prints a markdown table; exits non-zero when it cannot parse what
it ran.

    /usr/bin/python3 bench/march_bench.py --voxwall build/master/voxwall [--unshaded]
        [--volume ct-phantom] [--error-picture PATH]

--error-picture writes where the error sits: a crop of the default and the `--exact` pictures
(top) and each one's largest RGB channel difference from the converged render, times 16 (bottom).
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
    p.add_argument("--volume", choices=["mri", "ct-phantom"], default="mri")
    p.add_argument("--error-picture", metavar="PATH", help="write where the error sits (PNG)")
    p.add_argument("--crop", default="480x360", help="the error picture's crop, at the centre")
    args = p.parse_args()
    if args.volume == "mri" and not os.path.exists(MRI):
        fail(f"{MRI} is missing (apt-get install mricron-data)")
    work = tempfile.mkdtemp(prefix="march-bench-")
    try:
        vwz = os.path.join(work, "volume.vwz")
        if args.volume == "mri":
            subprocess.run([args.voxwall, "compress", MRI, "-o", vwz, "-q"], check=True)
        else:
            subprocess.run([args.voxwall, "generate", "shepp-logan", "--type", "int16", "-o", vwz],
                           check=True, stdout=subprocess.DEVNULL)
        rows = []
        for name, extra in SETTINGS:
            out = os.path.join(work, str(len(rows)))
            rows.append((name, out) + render(args, vwz, out, extra))
        ref = load(os.path.join(rows[0][1], "frame_00001.png"))
        exact_time = rows[1][2]
        title = "MRI template" if args.volume == "mri" else "Shepp-Logan CT phantom (int16)"
        print(f"{title}, {args.size}, {'unshaded' if args.unshaded else 'shaded'}, one rank "
              f"x {args.threads} threads, the second frame of a still view")
        print("| setting | march | render | / `--exact` | samples | rays cast | PSNR vs converged |")
        print("|---|---|---|---|---|---|---|")
        for name, out, seconds, samples, rays, stride, march in rows:
            quality = psnr(load(os.path.join(out, "frame_00001.png")), ref)
            shown = "reference" if out == rows[0][1] else f"{quality:.1f} dB"
            print(f"| {name} | {march} | {seconds:.2f} s | {seconds / exact_time:.2f} | "
                  f"{samples / 1e6:.0f} M | {rays:.0%} (lattice {stride}) | {shown} |")
        if args.error_picture:
            pictures = [load(os.path.join(rows[i][1], "frame_00001.png")) for i in (-1, 1)]
            error_picture(args, ref, pictures)
    finally:
        shutil.rmtree(work)


def error_picture(args, ref, pictures):
    """Top: the crop of each picture; bottom: its largest RGB difference from `ref`, times 16."""
    from PIL import Image
    w, h = (int(v) for v in args.crop.split("x"))
    y0, x0 = (ref.shape[0] - h) // 2, (ref.shape[1] - w) // 2
    if y0 < 0 or x0 < 0:
        fail(f"--crop {args.crop} is larger than the frame")
    crop = np.s_[y0:y0 + h, x0:x0 + w]
    top = np.concatenate([p[crop][..., :3] for p in pictures], axis=1)
    diffs = [np.abs(p[crop][..., :3] - ref[crop][..., :3]).max(axis=2) for p in pictures]
    for label, picture, d in zip(("default", "--exact"), pictures, diffs):
        print(f"{label}: in the crop, largest difference {d.max():.0f} levels, "
              f"PSNR {psnr(picture[crop], ref[crop]):.1f} dB")
    bottom = np.concatenate([np.minimum(d * 16, 255) for d in diffs], axis=1)
    bottom = np.repeat(bottom[..., None], 3, axis=2)
    both = np.concatenate([top, bottom], axis=0).astype(np.uint8)
    grey = (both[..., 0] == both[..., 1]).all() and (both[..., 0] == both[..., 2]).all()
    Image.fromarray(both[..., 0] if grey else both).save(args.error_picture, optimize=True)
    print(f"error picture: {args.error_picture}")


if __name__ == "__main__":
    main()
