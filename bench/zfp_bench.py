#!/usr/bin/python3
"""The zfp codec against the zfp command line, and where the other codecs stand against both.

Volumes: ch2better (uint8 MRI), a float32 volume (the MRI as float32 with smooth noise, as in
ksvd_bench.py), a CT-like int16 volume (the 3D Shepp-Logan phantom at 192^3 in Hounsfield units
with CT's noise) and a smooth field (Marschner-Lobb, 160^3 float32). On each: Debian's `zfp` 1.0
command line in fixed precision and fixed rate on the whole volume, voxwall's zfp codec at the
same settings (bricks of 16^3 coded on their own plus an index), in fixed accuracy and at size
targets, and vq, ksvd (one level) and tvq at size targets. Every method's output is decoded and
compared with the input by the same PSNR (peak = the input's value range, as
voxwall::codec::psnr) and maximum error; the command line's integer output is rounded and
clamped to the input's range as the codec does. For each codec row in fixed precision, "vs CLI"
is its PSNR minus the command line's at the same bits per voxel (interpolated between the
command line's precision points). Then decode speed and the 1920x1080 frame time of the
fixed-precision files against raw (voxwall_bench_vq).
Prints tables, writes results.json and rd-<volume>.png.

Run from the repository root after building: /usr/bin/python3 bench/zfp_bench.py
(Debian's python3 with numpy and matplotlib; scripts/install-deps.sh bench installs zfp.)
"""
import argparse
import json
import os
import sys

import numpy as np

from ksvd_bench import make_inputs, run, speed, speed_table, table, voxwall_run, zfp_runs
from rd_common import plot


def codec_rows(voxwall, work, name, a, precisions, rates, tolerances, targets, peers):
    rows = []
    for p in precisions:
        rows.append(voxwall_run(voxwall, work, name, a, "zfp", "precision %g" % p,
                                ["--precision", str(int(p))], method="voxwall zfp precision"))
    for r in rates:
        rows.append(voxwall_run(voxwall, work, name, a, "zfp", "rate %g" % r, ["--rate", str(r)],
                                method="voxwall zfp rate"))
    span = float(a.max()) - float(a.min())
    for t in tolerances:  # fractions of the value range
        rows.append(voxwall_run(voxwall, work, name, a, "zfp", "tolerance %g range" % t,
                                ["--tolerance", repr(t * span)], method="voxwall zfp accuracy"))
    for codec in ["zfp"] + peers:
        if codec == "vq" and a.dtype == np.float32:
            continue  # vq takes integer data only
        extra = ["--levels", "1"] if codec == "ksvd" else []
        for bpv in targets:
            rows.append(voxwall_run(voxwall, work, name, a, codec, "target %g" % bpv,
                                    ["--bits-per-voxel", str(bpv)] + extra,
                                    method="%s target" % codec))
    return [r for r in rows if r]


def target_table(name, rows, targets):
    """Each codec at each size target: bits per voxel reached and PSNR; the last column says
    which codec leads at that target (zfp's target rows are its fixed-accuracy mode at the
    power-of-two tolerance whose file fits)."""
    codecs = []
    for r in rows:
        if r["method"].endswith(" target") and r["method"][:-7] not in codecs:
            codecs.append(r["method"][:-7])
    print("\n### %s: every codec at the size targets (bits/voxel reached, PSNR dB)\n" % name)
    print("| target | " + " | ".join(codecs) + " | leads |")
    print("|---|" + "---|" * (len(codecs) + 1))
    for t in targets:
        cells, best = [], None
        for c in codecs:
            hit = [r for r in rows if r["method"] == c + " target" and
                   r["setting"] == "target %g" % t]
            if not hit:
                cells.append("refused")
                continue
            r = hit[0]
            cells.append("%.3f / %s" % (r["bpv"], "lossless" if r["psnr"] == float("inf")
                                        else "%.2f" % r["psnr"]))
            if best is None or r["psnr"] > best[1]:
                best = (c, r["psnr"])
        print("| %g | %s | %s |" % (t, " | ".join(cells), best[0] if best else "-"))


def versus_cli(rows):
    """Adds "vs_cli" (dB) to the codec's precision rows: its PSNR minus the command line's at the
    same rate, where the command line's precision points bracket that rate."""
    cli = sorted((r["bpv"], r["psnr"]) for r in rows if r["method"] == "zfp fixed-precision")
    if len(cli) < 2:
        sys.exit("need at least two zfp command-line precision points to compare with")
    for r in rows:
        if r["method"] == "voxwall zfp precision" and cli[0][0] <= r["bpv"] <= cli[-1][0]:
            r["vs_cli"] = r["psnr"] - float(np.interp(r["bpv"], [c[0] for c in cli],
                                                      [c[1] for c in cli]))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--voxwall", default="build/master/voxwall")
    p.add_argument("--bench", default="build/bench/voxwall_bench_vq")
    p.add_argument("--out", default="bench-out/zfp")
    p.add_argument("--volumes", default="mri,float,ct,smooth")
    p.add_argument("--precisions", default="6,8,10,12,14")
    p.add_argument("--rates", default="1,2,4")
    p.add_argument("--tolerances", default="0.001,0.01,0.05")
    p.add_argument("--targets", default="0.25,0.5,1,2")
    p.add_argument("--peers", default="vq,ksvd,tvq",
                   help="codecs also run at the size targets (vq's k-means takes minutes each)")
    p.add_argument("--threads", type=int, default=0)
    args = p.parse_args()
    os.makedirs(args.out, exist_ok=True)
    numbers = lambda s: [float(v) for v in s.split(",") if v]
    results = {}
    for name, a in make_inputs(args.voxwall, args.out, args.volumes.split(",")):
        print("== %s: %dx%dx%d %s" % (name, a.shape[2], a.shape[1], a.shape[0], a.dtype),
              flush=True)
        rows = zfp_runs(args.out, name, a, numbers(args.rates), numbers(args.precisions))
        rows += codec_rows(args.voxwall, args.out, name, a, numbers(args.precisions),
                           numbers(args.rates), numbers(args.tolerances), numbers(args.targets),
                           [c for c in args.peers.split(",") if c])
        versus_cli(rows)
        raw = voxwall_run(args.voxwall, args.out, name, a, "raw", "lossless", [])
        zfp_files = [r for r in rows if r["method"] == "voxwall zfp precision"]
        results[name] = {"rows": rows, "speed": speed(args.bench, raw["file"], zfp_files,
                                                      args.threads)}
        table(name, rows)
        print("\n| voxwall zfp precision | bits/voxel | PSNR dB | vs CLI at equal rate dB |")
        print("|---|---|---|---|")
        for r in rows:
            if "vs_cli" in r:
                print("| %s | %.3f | %.2f | %+.2f |" % (r["setting"], r["bpv"], r["psnr"],
                                                       r["vs_cli"]))
        target_table(name, rows, numbers(args.targets))
        speed_table(name, results[name]["speed"])
        plot(os.path.join(args.out, "rd-%s.png" % name), "rate-distortion: %s" % name, rows,
             points=("vq target", "ksvd target", "tvq target"))
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    print("\nwrote %s/results.json and rd-*.png" % args.out)


if __name__ == "__main__":
    main()
