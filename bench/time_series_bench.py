#!/usr/bin/env python3
"""Time series: each codec's file of a generated series with its model shared across the steps
(the default) against every step coded on its own (--steps-alone), and playback: the frame time
of `render --time` (a step a frame) against frames of one step, same view, same run.

  bench/time_series_bench.py [--voxwall build/master/voxwall] [--steps 16] [--size 96]
                             [--codecs raw,vq,ksvd,tvq] [--ranks 2] [--frames 16]

Prints two tables. Stops with an error when voxwall's output cannot be parsed."""
import argparse
import math
import os
import re
import subprocess
import sys
import tempfile

# Each codec's settings for the series: lossless where the codec is, a fixed tolerance otherwise.
SETTINGS = {
    "raw": [],
    "vq": [],
    "svmm": [],
    "ksvd": ["--tolerance", "0.01"],
    "tvq": ["--bits-per-voxel", "0.25"],
    "zfp": ["--tolerance", "1"],
}


def run(args, **kw):
    r = subprocess.run(args, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit("failed: " + " ".join(args) + "\n" + r.stdout + r.stderr)
    return r.stdout + r.stderr


def steps_of(voxwall, vwz):
    """(bytes of the file, mean PSNR over steps (inf when every step is lossless), steps)."""
    out = run([voxwall, "info", vwz])
    size = re.search(r"^size\s+.*\((\d+) bytes\)", out, re.M)
    lines = re.findall(r"^step (\d+)\s+.*?, (lossless|.*PSNR ([\d.]+) dB.*)$", out, re.M)
    if not size or not lines:
        sys.exit("cannot parse `voxwall info " + vwz + "`:\n" + out)
    psnrs = [math.inf if q == "lossless" else float(p) for _, q, p in lines]
    finite = [p for p in psnrs if p != math.inf]
    mean = sum(finite) / len(finite) if finite else math.inf
    return int(size.group(1)), mean, len(lines)


def mean_frame_ms(out):
    m = re.search(r"mean frame ([\d.]+) ms", out)
    if not m:
        sys.exit("cannot parse the render's totals:\n" + out)
    return float(m.group(1))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--voxwall", default="build/master/voxwall")
    ap.add_argument("--steps", type=int, default=16)
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--codecs", default="raw,vq,ksvd,tvq")
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--frames", type=int, default=16)
    ap.add_argument("--render-size", default="960x540")
    a = ap.parse_args()
    voxwall = os.path.abspath(a.voxwall)
    with tempfile.TemporaryDirectory() as tmp:
        series = os.path.join(tmp, "blobs.nii")
        run([voxwall, "generate", "blobs", "--steps", str(a.steps), "--size", str(a.size),
             "-o", series])
        voxels = a.steps * a.size ** 3
        print(f"## {a.steps} steps of {a.size}^3 uint8 (generate blobs), shared model vs "
              "each step on its own\n")
        print("| codec | settings | shared: bits/voxel | shared: mean PSNR | alone: bits/voxel | "
              "alone: mean PSNR | shared / alone size |")
        print("| --- | --- | ---: | ---: | ---: | ---: | ---: |")
        files = {}
        for codec in a.codecs.split(","):
            row = []
            for mode in ("shared", "alone"):
                vwz = os.path.join(tmp, f"{codec}-{mode}.vwz")
                extra = ["--steps-alone"] if mode == "alone" else []
                run([voxwall, "compress", "-q", series, "-o", vwz, "--codec", codec] +
                    SETTINGS.get(codec, []) + extra)
                size, psnr, steps = steps_of(voxwall, vwz)
                if steps != a.steps:
                    sys.exit(f"{vwz}: info lists {steps} steps, not {a.steps}")
                row.append((size, psnr))
                files[(codec, mode)] = vwz
            (s_size, s_psnr), (a_size, a_psnr) = row
            fmt = lambda p: "lossless" if p == math.inf else f"{p:.2f} dB"
            print(f"| {codec} | {' '.join(SETTINGS.get(codec, [])) or 'lossless'} | "
                  f"{8 * s_size / voxels:.3f} | {fmt(s_psnr)} | {8 * a_size / voxels:.3f} | "
                  f"{fmt(a_psnr)} | {s_size / a_size:.2f} |")

        print(f"\n## Playback on {a.ranks} rank(s), {a.render_size}, {a.frames} frames, camera "
              "still: a step a frame against one step in every frame\n")
        print("| codec | step a frame: mean frame ms | one step: mean frame ms | ratio |")
        print("| --- | ---: | ---: | ---: |")
        mpirun = ["mpirun", "--oversubscribe", "--bind-to", "none", "-np", str(a.ranks)]
        if os.geteuid() == 0:
            mpirun.insert(1, "--allow-run-as-root")
        for codec in a.codecs.split(","):
            vwz = files[(codec, "shared")]
            common = [voxwall, "render", vwz, "--size", a.render_size, "--path", "still",
                      "--shading", "--no-write", "--frames", str(a.frames)]
            last = min(a.steps, a.frames) - 1
            playing = mean_frame_ms(run(mpirun + common + ["--time", f"0:{last}"]))
            still = mean_frame_ms(run(mpirun + common + ["--time", "0"]))
            print(f"| {codec} | {playing:.1f} | {still:.1f} | {playing / still:.2f} |")


if __name__ == "__main__":
    main()
