#!/usr/bin/python3
"""Page decode per codec: how many voxels a second one core turns into the CPU backend's decoded
pages (the 32^3-voxel pages rays sample), voxel by voxel through the codec's view (the way every
page was decoded before brick views were decoded a brick at a time), by page without the memo of
decoded bricks (zfp and ksvd: the way before it), and the way the renderer does now, in page
order and with the pages shuffled.

The volume is the MRI template (mricron-data) at --scale (1: 301x370x316) as scale_bench.py
makes it: trilinear upsampling with mild Gaussian noise of sigma 1.5, so no two bricks are alike
(which is what makes a codebook's or dictionary's decode work), generated here into a temporary
directory and never kept. Each codec compresses it with scale_bench.py's options (lossless vq,
lossless svmm, ksvd/tvq/zfp at their defaults), and voxwall_bench_pages decodes every page of
each file on one thread, best pass of --seconds.

Prints a markdown table; stops with an error when a run fails or prints something it cannot
parse. Needs a release build (build/) and numpy.

Run from the repository root: /usr/bin/python3 bench/page_decode_bench.py [--scale 1]
"""
import argparse
import os
import re
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from scale_bench import OPTIONS, generate, run  # noqa: E402

LINE = re.compile(r"^pages (\S+) codec (\S+) voxels (\d+) pages (\d+) by-voxel ([0-9.]+) "
                  r"no-memo ([0-9.]+) by-page ([0-9.]+) shuffled-no-memo ([0-9.]+) "
                  r"shuffled ([0-9.]+)$", re.M)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--build", default="build")
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--seconds", type=float, default=2.0)
    p.add_argument("--codecs", default="vq,svmm,ksvd,tvq,zfp")
    args = p.parse_args()
    voxwall = os.path.join(args.build, "master", "voxwall")
    bench = os.path.join(args.build, "bench", "voxwall_bench_pages")
    for tool in (voxwall, bench):
        if not os.access(tool, os.X_OK):
            sys.exit("%s is missing: build the release tree first (cmake --build %s)" %
                     (tool, args.build))
    codecs = args.codecs.split(",")
    with tempfile.TemporaryDirectory(prefix="voxwall-pages-") as work:
        source, dims = generate(voxwall, args.scale, work)
        files = []
        for codec in codecs:
            out = os.path.join(work, codec + ".vwz")
            run([voxwall, "compress", source, "--dims", ",".join(map(str, dims)), "--type",
                 "uint8", "--codec", codec, "-q", "-o", out] + OPTIONS.get(codec, []))
            files.append(out)
        text = run([bench, "--seconds", str(args.seconds)] + files)
        rows = {m.group(2): m for m in LINE.finditer(text)}
        missing = [c for c in codecs if c not in rows]
        if missing:
            sys.exit("no measurement for %s in:\n%s" % (", ".join(missing), text))
        print("Page decode on one core, %s voxels (%d pages of 32^3), Mvox/s of the volume:\n" %
              ("x".join(map(str, dims)), int(rows[codecs[0]].group(4))))
        print("| codec | bits/voxel | voxel by voxel | by page, no memo | by page (now) | "
              "speed-up | shuffled pages, no memo | shuffled pages (now) |")
        print("|---|---|---|---|---|---|---|---|")
        for codec, path in zip(codecs, files):
            m = rows[codec]
            voxels = int(m.group(3))
            slow, alone, fast, mixedAlone, mixed = (float(m.group(i)) for i in range(5, 10))
            if min(slow, alone, fast, mixedAlone, mixed) <= 0:
                sys.exit("a rate of 0 for %s:\n%s" % (codec, text))
            bpv = 8.0 * os.path.getsize(path) / voxels
            print("| %s | %.2f | %.1f | %.1f | %.1f | %.2fx | %.1f | %.1f |" %
                  (codec, bpv, slow, alone, fast, fast / slow, mixedAlone, mixed))


if __name__ == "__main__":
    main()
