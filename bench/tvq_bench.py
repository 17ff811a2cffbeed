#!/usr/bin/python3
"""Rate-distortion, encode time and decode speed of the tvq codec against its peers.

On ch2better (uint8 MRI) and a float32 volume (the MRI as float32 with smooth noise, as
bench/ksvd_bench.py makes it): tvq at size targets with the KLT and the DCT, without
classification (the paper's Figure 8), with one sub-volume for the MRI (--subvolume 512), and at
fixed code bits (several codebook sizes); beside them in the same run plain VQ of the same 4^3
blocks (our vq with --codebook plain), our vq, svmm and ksvd at matching rates, and ZFP. Every
file is decoded and compared with the input by the same PSNR (peak = the input's value range).
Then the decode rate (Mvoxels/s on one core) and the 1920x1080 frame time of the tvq files
against the raw codec (voxwall_bench_vq). Prints tables, writes results.json and rd-<volume>.png.

Run from the repository root after building: /usr/bin/python3 bench/tvq_bench.py
"""
import argparse
import json
import os
import sys

from ksvd_bench import make_inputs, need, run, speed, speed_table, table, voxwall_run, zfp_runs
from rd_common import plot


def check_stored_psnr(row):
    """tvq stores the PSNR of every progressive level; the last must be what we measured."""
    log, _ = run([ARGS.voxwall, "info", row["file"]])
    stored = need(r"quality\s+lossy, PSNR ([\d.]+) dB", log, "tvq's stored PSNR")
    if abs(float(stored.group(1)) - row["psnr"]) > 0.02:
        sys.exit("tvq's stored PSNR %s differs from the measured %.2f (%s)" %
                 (stored.group(1), row["psnr"], row["file"]))
    levels = need(r"progressive\s+dc \(mean\) ([\d.]+) dB, lp \(\+lowpass\) ([\d.]+) dB, "
                  r"bp \(\+bandpass\) ([\d.]+) dB", log, "tvq's progressive levels")
    row["levels"] = [float(levels.group(i)) for i in (1, 2, 3)] + [row["psnr"]]


def tvq_runs(name, a, targets, bits):
    rows = []

    def tvq(setting, options, method):
        row = voxwall_run(ARGS.voxwall, ARGS.out, name, a, "tvq", setting, options, method)
        if row:
            check_stored_psnr(row)
            rows.append(row)

    for transform in ("klt", "dct"):
        for bpv in targets:
            tvq("%s target %g" % (transform, bpv),
                ["--transform", transform, "--bits-per-voxel", str(bpv)], "tvq " + transform)
    for bpv in targets[:2]:
        tvq("klt target %g, no classes" % bpv, ["--bits-per-voxel", str(bpv), "--no-classes"],
            "tvq klt without classes")
        tvq("klt target %g, --subvolume 512" % bpv,
            ["--bits-per-voxel", str(bpv), "--subvolume", "512"], "tvq klt one sub-volume")
    for b in bits:
        tvq("klt --codebook-bits %d" % b, ["--codebook-bits", str(b)], "tvq klt code bits")
    return rows


def peer_runs(name, a, reductions, ksvd_targets):
    rows = []
    if a.dtype != "float32":  # vq and svmm refuse float32
        rows.append(voxwall_run(ARGS.voxwall, ARGS.out, name, a, "vq", "plain 1/64",
                                ["--codebook", "plain", "--reduction", "64"], "vq plain"))
        for k in reductions:
            rows.append(voxwall_run(ARGS.voxwall, ARGS.out, name, a, "vq", "1/%d" % k,
                                    ["--reduction", str(k)]))
        for quality in (60, 80):
            rows.append(voxwall_run(ARGS.voxwall, ARGS.out, name, a, "svmm", "quality %d" % quality,
                                    ["--quality", str(quality)]))
    for bpv in ksvd_targets:
        rows.append(voxwall_run(ARGS.voxwall, ARGS.out, name, a, "ksvd", "target %g" % bpv,
                                ["--bits-per-voxel", str(bpv), "--levels", "1"]))
    return [r for r in rows if r]


def tvq_table(name, rows):
    print("\n### %s: tvq's progressive levels (PSNR dB)\n" % name)
    print("| setting | bits/voxel | mean | + lowpass | + bandpass | all | encode s |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print("| %s | %.3f | %s | %.1f |" % (r["setting"], r["bpv"],
                                           " | ".join("%.2f" % v for v in r["levels"]),
                                           r["seconds"]))


def main():
    global ARGS
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--voxwall", default="build/master/voxwall")
    p.add_argument("--bench", default="build/bench/voxwall_bench_vq")
    p.add_argument("--out", default="bench-out/tvq")
    p.add_argument("--volumes", default="mri,float")
    p.add_argument("--targets", default="0.25,0.5,1")
    p.add_argument("--code-bits", default="12,20,28")
    p.add_argument("--vq-reductions", default="8,16,64")
    p.add_argument("--ksvd-targets", default="0.25,0.5")
    p.add_argument("--zfp-rates", default="0.5,1,2")
    p.add_argument("--threads", type=int, default=0)
    ARGS = p.parse_args()
    os.makedirs(ARGS.out, exist_ok=True)
    split = lambda s: [v for v in s.split(",") if v]
    results = {}
    for name, a in make_inputs(ARGS.voxwall, ARGS.out, split(ARGS.volumes)):
        print("== %s: %dx%dx%d %s" % (name, a.shape[2], a.shape[1], a.shape[0], a.dtype),
              flush=True)
        tvq = tvq_runs(name, a, [float(v) for v in split(ARGS.targets)],
                       [int(v) for v in split(ARGS.code_bits)])
        rows = tvq + peer_runs(name, a, [int(v) for v in split(ARGS.vq_reductions)],
                               [float(v) for v in split(ARGS.ksvd_targets)])
        rows += zfp_runs(ARGS.out, name, a, [float(v) for v in split(ARGS.zfp_rates)], [])
        raw_vwz = voxwall_run(ARGS.voxwall, ARGS.out, name, a, "raw", "lossless", [])["file"]
        fast = [r for r in tvq if "target" in r["setting"] and "classes" not in r["setting"]]
        others = [r for r in rows if r["method"] in ("vq", "ksvd")]
        results[name] = {"rows": rows,
                         "speed": speed(ARGS.bench, raw_vwz, fast + others, ARGS.threads)}
        table(name, rows)
        tvq_table(name, tvq)
        speed_table(name, results[name]["speed"])
        plot(os.path.join(ARGS.out, "rd-%s.png" % name), "rate-distortion: %s" % name, rows,
             points=("tvq klt code bits", "vq plain"))
    with open(os.path.join(ARGS.out, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    print("\nwrote %s/results.json and rd-*.png" % ARGS.out)


ARGS = None

if __name__ == "__main__":
    main()
