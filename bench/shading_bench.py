#!/usr/bin/python3
"""What shading costs, per codec, in one run: unshaded frames, shaded frames with the six-sample
gradients (`--gradients samples`) and shaded frames with cell gradients (`--gradients cell`, the
default), on the same file, camera and transfer function.

The volume is the MRI template (mricron-data), or a generated 256^3 Shepp-Logan phantom without
it, stored as raw, lossless vq, svmm (--quality 100), ksvd (defaults, --levels 1) and tvq
(defaults). Every render is two 1920x1080 frames of the same view (`voxwall render --frames 2
--no-write`) with the VTK comparison's transfer function (bench/data/vtk-comparison-tf.json). The
second frame is the one measured: the first also decodes the pages of a brick-coded volume (vq,
ksvd, tvq) that its rays reach (`--decode-cache`, docs/rendering.md), which later frames reuse;
the first frame's time is printed beside it. The variants are run in turn, --reps times, and the
fastest of each is kept (the VM is shared: compare ratios within one run). Prints a markdown
table: ms per frame, shaded / unshaded, samples / cell, and each codec's frame / raw's frame.

Run from the repository root after building: /usr/bin/python3 bench/shading_bench.py
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

MRI = "/usr/share/mricron/templates/ch2better.nii.gz"
FRAME = re.compile(r"^frame ([12])/2: ([0-9.]+) ms", re.M)


def run(cmd):
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if r.returncode != 0:
        sys.exit("failed: %s\n%s" % (" ".join(cmd), r.stdout))
    return r.stdout


def frame_ms(out, cmd):
    """The (first, second) frame times of a two-frame render."""
    times = {int(m.group(1)): float(m.group(2)) for m in FRAME.finditer(out)}
    if sorted(times) != [1, 2]:
        sys.exit("cannot find both frame times in the output of %s:\n%s" % (" ".join(cmd), out))
    return times[1], times[2]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--voxwall", default="build/master/voxwall")
    ap.add_argument("--size", default="1920x1080")
    ap.add_argument("--threads", default="1")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--codecs", default="raw,vq,svmm,ksvd,tvq")
    args = ap.parse_args()
    tf = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "vtk-comparison-tf.json")
    work = tempfile.mkdtemp(prefix="voxwall-shading-")
    source = MRI if os.path.exists(MRI) else "generated:shepp-logan:256"
    options = {"raw": [], "vq": [], "svmm": ["--quality", "100"], "ksvd": ["--levels", "1"],
               "tvq": []}
    codecs = args.codecs.split(",")
    files = {}
    for codec in codecs:
        if codec not in options:
            sys.exit("unknown codec %s (expected raw, vq, svmm, ksvd or tvq)" % codec)
        files[codec] = os.path.join(work, codec + ".vwz")
        print("compressing %s as %s" % (source, codec), file=sys.stderr)
        run([args.voxwall, "compress", source, "--codec", codec, "-o", files[codec], "-q"]
            + options[codec])
    variants = [("unshaded", []), ("samples", ["--shading", "--gradients", "samples"]),
                ("cell", ["--shading", "--gradients", "cell"])]
    best, firsts = {}, {}
    for rep in range(args.reps):
        for codec in codecs:
            for name, extra in variants:
                cmd = [args.voxwall, "render", files[codec], "--size", args.size, "--tf", tf,
                       "--threads", args.threads, "--frames", "2", "--no-write", "--exact"] + extra
                first_ms, ms = frame_ms(run(cmd), cmd)
                key = (codec, name)
                best[key] = min(best.get(key, ms), ms)
                firsts[key] = min(firsts.get(key, first_ms), first_ms)
        print("rep %d of %d done" % (rep + 1, args.reps), file=sys.stderr)
    print("%s, %s, %s thread(s), fastest of %d runs (ms per frame: the second frame; the first "
          "frame, which decodes pages, in the last columns)\n"
          % (os.path.basename(source), args.size, args.threads, args.reps))
    print("| codec | unshaded | shaded, six samples | shaded, cell | shaded / unshaded (cell) "
          "| samples / cell | unshaded / raw | shaded (cell) / raw | first frame unshaded "
          "| first frame shaded (cell) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for codec in codecs:
        u, s, c = best[(codec, "unshaded")], best[(codec, "samples")], best[(codec, "cell")]
        vs_raw = "| %.2f | %.2f |" % (u / best[("raw", "unshaded")], c / best[("raw", "cell")]) \
            if "raw" in codecs else "| | |"
        print("| %s | %.0f | %.0f | %.0f | %.2f | %.2f %s %.0f | %.0f |"
              % (codec, u, s, c, c / u, s / c, vs_raw, firsts[(codec, "unshaded")],
                 firsts[(codec, "cell")]))


if __name__ == "__main__":
    main()
