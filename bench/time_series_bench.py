#!/usr/bin/env python3
"""Time series: each codec's file of a generated series with its model shared across the steps
(the default) against every step coded on its own (--steps-alone); vq reduced with one codebook
against a codebook a step at equal PSNR; and playback: in one `render --time` run that shows each
step for two frames, the frames that open a new step against the frames that repeat one (same
view, same content, same run), with --rounds runs of every codec in turn (each ratio over raw's of
the same round: median and range) and the samples the rays took over raw's (a lossy file's
ringing can make them more).

  bench/time_series_bench.py [--voxwall build/master/voxwall] [--steps 16] [--size 96]
                             [--codecs raw,vq,ksvd,tvq] [--ranks 2] [--vq-rates 0.25,0.5]
                             [--render-size 960x540] [--rounds 1]

Prints three tables. Stops with an error when voxwall's output cannot be parsed."""
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
    "tvq": ["--bits-per-voxel", "0.15"],
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


def step_frames(out):
    """(mean ms of the frames that show a new step, mean ms of those that repeat the step before,
    the job's first frame left out (it opens the file and warms up); the samples of every frame:
    a lossy codec's ringing can make the rays take more than raw data's)."""
    new, repeat, before = [], [], None
    for f, step, ms in re.findall(r"^frame (\d+)/\d+, time step (\d+): ([\d.]+) ms", out, re.M):
        if int(f) > 1:
            (new if step != before else repeat).append(float(ms))
        before = step
    samples = [int(n) for n in re.findall(r"^  (\d+) samples, ", out, re.M)]
    if not new or not repeat or len(samples) != len(new) + len(repeat) + 1:
        sys.exit("cannot parse the render's frame lines:\n" + out)
    return sum(new) / len(new), sum(repeat) / len(repeat), sum(samples)


def coded(voxwall, series, vwz, args, voxels):
    """(bits per voxel, mean PSNR) of `series` compressed with `args`."""
    run([voxwall, "compress", "-q", series, "-o", vwz] + args)
    size, psnr, _ = steps_of(voxwall, vwz)
    return 8 * size / voxels, psnr


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--voxwall", default="build/master/voxwall")
    ap.add_argument("--steps", type=int, default=16)
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--codecs", default="raw,vq,ksvd,tvq")
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--vq-rates", default="0.25,0.5", help="empty: no vq rate table")
    ap.add_argument("--render-size", default="960x540")
    ap.add_argument("--rounds", type=int, default=1,
                    help="playback runs of every codec in turn (the VM is noisy)")
    a = ap.parse_args()
    if "raw" not in a.codecs.split(","):
        sys.exit("--codecs must include raw: every playback ratio is over raw's")
    if a.rounds < 1:
        sys.exit("--rounds must be at least 1")
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

        if "vq" in a.codecs.split(",") and a.vq_rates:
            print("\n## vq reduced: one codebook for every step against a codebook a step at "
                  "equal PSNR\n")
            print("| target bits/voxel | shared: bits/voxel | shared: mean PSNR | alone at that "
                  "PSNR: bits/voxel | alone: mean PSNR | shared / alone size |")
            print("| ---: | ---: | ---: | ---: | ---: | ---: |")
            vwz = os.path.join(tmp, "vq-rate.vwz")
            for rate in [float(r) for r in a.vq_rates.split(",")]:
                s_bpv, s_psnr = coded(voxwall, series, vwz,
                                      ["--codec", "vq", "--bits-per-voxel", str(rate)], voxels)
                # The rate at which a codebook a step reaches the same mean PSNR, by bisection.
                lo, hi, best = 0.02, 8.0, None
                for _ in range(10):
                    mid = math.sqrt(lo * hi)
                    bpv, psnr = coded(voxwall, series, vwz, ["--codec", "vq", "--bits-per-voxel",
                                                             f"{mid:.4f}", "--steps-alone"], voxels)
                    if psnr >= s_psnr:
                        hi, best = mid, (bpv, psnr)
                    else:
                        lo = mid
                    if best and best[1] - s_psnr < 0.1:
                        break
                if not best:
                    sys.exit(f"vq --steps-alone reaches no {s_psnr:.2f} dB below 8 bits/voxel")
                print(f"| {rate} | {s_bpv:.3f} | {s_psnr:.2f} dB | {best[0]:.3f} | "
                      f"{best[1]:.2f} dB | {s_bpv / best[0]:.2f} |")

        frames = 2 * a.steps
        print(f"\n## Playback on {a.ranks} rank(s), {a.render_size}, camera still, each step "
              f"shown for two frames ({frames} frames): frames that open a new step against "
              f"frames that repeat the step before; {a.rounds} round(s) of every codec in turn, "
              "each ratio over raw's of the same round, median (lowest-highest)\n")
        print("| codec | new step: mean frame ms | same step: mean frame ms | ratio | new step / "
              "raw's new step | all frames / raw's | samples / raw's |")
        print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
        mpirun = ["mpirun", "--oversubscribe", "--bind-to", "none", "-np", str(a.ranks)]
        if os.geteuid() == 0:
            mpirun.insert(1, "--allow-run-as-root")
        codecs = a.codecs.split(",")
        runs = {c: [] for c in codecs}  # per round: (new, same)
        for _ in range(a.rounds):
            for codec in codecs:
                out = run(mpirun + [voxwall, "render", files[(codec, "shared")], "--size",
                                    a.render_size, "--path", "still", "--shading", "--exact",
                                    "--no-write", "-v", "--frames", str(frames), "--time",
                                    f"0:{a.steps - 1}"])
                runs[codec].append(step_frames(out))

        def spread(values, fmt):
            v = sorted(values)
            mid = v[len(v) // 2] if len(v) % 2 else (v[len(v) // 2 - 1] + v[len(v) // 2]) / 2
            return fmt.format(mid) + (f" ({fmt.format(v[0])}-{fmt.format(v[-1])})"
                                      if len(v) > 1 else "")

        for codec in codecs:
            r, raw = runs[codec], runs["raw"]
            print(f"| {codec} | {spread([n for n, _, _ in r], '{:.1f}')} | "
                  f"{spread([s for _, s, _ in r], '{:.1f}')} | "
                  f"{spread([n / s for n, s, _ in r], '{:.2f}')} | "
                  f"{spread([n / rn for (n, _, _), (rn, _, _) in zip(r, raw)], '{:.2f}')} | "
                  f"{spread([(n + s) / (rn + rs) for (n, s, _), (rn, rs, _) in zip(r, raw)], '{:.2f}')} | "
                  f"{r[0][2] / raw[0][2]:.2f} |")

if __name__ == "__main__":
    main()
