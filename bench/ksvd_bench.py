#!/usr/bin/python3
"""Rate-distortion, training cost and decode speed of the ksvd codec against vq, svmm and ZFP.

On ch2better (uint8 MRI) and a float32 volume (the MRI as float32 with smooth noise added):
ksvd at the (M, S) settings of the COVRA paper's Table 2 (M4 S16, M6 S8, M6 S4, M8 S4; K 1024)
and at size targets, a coreset sweep (Table 1), our vq and svmm at matching rates (integer data
only: they refuse float32), and ZFP fixed-rate and fixed-precision. Every method's output is
decoded and compared with the input by the same PSNR (peak = the input's value range, as
voxwall::codec::psnr). Peak memory is what `voxwall compress` reports (its maximum resident set:
input, encoder and output together), and /usr/bin/time's for zfp. Then the decode
rate (Mvoxels/s on one core) and the 1920x1080 frame time of the ksvd files against the raw codec
(voxwall_bench_vq). Prints tables, writes results.json and rd-<volume>.png.

Run from the repository root after building: /usr/bin/python3 bench/ksvd_bench.py
(Debian's python3 with numpy and matplotlib; scripts/install-deps.sh bench installs zfp.)
"""
import argparse
import json
import os
import re
import subprocess
import sys
import time

import numpy as np

from rd_common import plot, psnr

MRI = "/usr/share/mricron/templates/ch2better.nii.gz"


MIB = {"B": 1 / 1048576.0, "KiB": 1 / 1024.0, "MiB": 1.0, "GiB": 1024.0}


def run(cmd, refusal=None):
    """Runs cmd; returns (output, seconds). Stops the bench when it fails, except with an error
    line containing `refusal` (a phrase or a tuple of them): then returns (None, that line)."""
    start = time.perf_counter()
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if r.returncode != 0:
        if refusal:
            phrases = (refusal,) if isinstance(refusal, str) else refusal
            line = [l for l in r.stdout.splitlines() if any(p in l for p in phrases)]
            if line:
                return None, line[0]
        sys.exit("failed: %s\n%s" % (" ".join(cmd), r.stdout))
    return r.stdout, time.perf_counter() - start


def peak_mib(log):
    """The peak memory `voxwall compress` reports ("peak memory 412.3 MiB")."""
    m = need(r"peak memory ([\d.]+) (B|KiB|MiB|GiB)", log, "the peak memory")
    return float(m.group(1)) * MIB[m.group(2)]


def need(pattern, text, what):
    m = re.search(pattern, text)
    if not m:
        sys.exit("cannot find %s in:\n%s" % (what, text))
    return m


# ---- inputs -------------------------------------------------------------------------------

def make_inputs(voxwall, work, which):
    """Returns [(name, array (z, y, x))]."""
    out = []
    mri = None
    if "mri" in which or "float" in which:
        vwz = os.path.join(work, "mri-raw.vwz")
        raw = os.path.join(work, "mri.raw")
        run([voxwall, "compress", MRI, "-o", vwz, "-q"])
        run([voxwall, "decompress", vwz, "-o", raw])
        mri = np.fromfile(raw, np.uint8).reshape(316, 370, 301)
    if "mri" in which:
        out.append(("ch2better", mri))
    if "float" in which:
        # The MRI as float32 in [0, 1] with smooth noise of 1% of the range (what a simulation
        # or a denoised microscopy volume looks like: no integer steps for a codec to exploit).
        rng = np.random.default_rng(7)
        noise = rng.normal(0.0, 1.0, mri.shape)
        for axis in range(3):
            noise = (np.roll(noise, 1, axis) + 2 * noise + np.roll(noise, -1, axis)) / 4
        a = (mri.astype(np.float64) / 255.0 + 0.01 * noise).astype(np.float32)
        out.append(("mri-float32", a))
    if "ct" in which:
        out.append(("ct-phantom-int16", ct_phantom(voxwall, work)))
    if "smooth" in which:
        out.append(("marschner-lobb-float32", generated(voxwall, work, "marschner-lobb", 160,
                                                        "float32", np.float32)))
    return out


def generated(voxwall, work, kind, size, typ, dtype):
    raw = os.path.join(work, "%s-%d-%s.raw" % (kind, size, typ))
    run([voxwall, "generate", kind, "--size", str(size), "--type", typ, "-o", raw])
    return np.fromfile(raw, dtype).reshape(size, size, size)


def ct_phantom(voxwall, work, size=192):
    """A CT-like int16 volume in Hounsfield units: the 3D Shepp-Logan phantom's regions as air
    (-1000), soft tissue (20-80 HU by region), fat-like lows and bone (up to 1000), with CT's
    noise (sigma 12 HU, lightly correlated between neighbours), about a real head CT's 7 Mvox."""
    v = generated(voxwall, work, "shepp-logan", size, "float32", np.float32).astype(np.float64)
    hi = float(v.max()) or 1.0
    v /= hi
    hu = np.where(v <= 0.0, -1000.0, np.where(v >= 0.9, 400.0 + 600.0 * v, -100.0 + 250.0 * v))
    rng = np.random.default_rng(11)
    noise = rng.normal(0.0, 1.0, v.shape)
    for axis in range(3):
        noise = (np.roll(noise, 1, axis) + 2 * noise + np.roll(noise, -1, axis)) / 4
    noise *= 12.0 / noise.std()
    return np.clip(np.rint(hu + noise), -1024, 3071).astype(np.int16)


def max_error(a, b):
    return float(np.max(np.abs(a.astype(np.float64) - b.astype(np.float64))))


def save_raw(work, name, a):
    src = os.path.join(work, name + ".raw")
    a.tofile(src)
    z, y, x = a.shape
    typ = {np.dtype(np.uint8): "uint8", np.dtype(np.int16): "int16",
           np.dtype(np.float32): "float32"}[a.dtype]
    return src, ["--dims", "%d,%d,%d" % (x, y, z), "--type", typ]


def show(row):
    print("  %-16s %-22s %7.3f bpv %7.2f dB %7.1f s %7.0f MiB" % (
        row["method"], row["setting"], row["bpv"], row["psnr"], row["seconds"], row["peak_mib"]),
        flush=True)


# ---- voxwall codecs -----------------------------------------------------------------------

# What ksvd, tvq and zfp say of a size target they cannot reach on a volume.
REFUSED = ("is below the smallest", "is above the largest")
# Level 0 only: vq, svmm's base level and ZFP store no pyramid for render --lod, so the
# rate-distortion rows compare like with like; one row shows what the pyramid adds.
FLAT = ["--levels", "1"]


def voxwall_run(voxwall, work, name, a, codec, setting, options, method=None):
    src, fmt = save_raw(work, name, a)
    tag = re.sub(r"[^a-z0-9.]+", "-", (codec + " " + setting).lower())
    vwz = os.path.join(work, "%s-%s.vwz" % (name, tag))
    dec = vwz + ".raw"
    log, seconds = run([voxwall, "compress", src] + fmt + ["--codec", codec] + options +
                       ["-o", vwz], refusal=REFUSED if "--bits-per-voxel" in options else None)
    if log is None:  # a size target below what the codec can reach on this volume: say so
        print("  %-16s %-22s refused: %s" % (method or codec, setting, seconds), flush=True)
        return None
    peak = peak_mib(log)
    run([voxwall, "decompress", vwz, "-o", dec])
    b = np.fromfile(dec, a.dtype).reshape(a.shape)
    os.remove(dec)
    row = {"method": method or codec, "setting": setting, "file": vwz,
           "bpv": 8.0 * os.path.getsize(vwz) / a.size, "psnr": psnr(a, b), "seconds": seconds,
           "peak_mib": peak, "max_err": max_error(a, b)}
    if codec == "ksvd":
        m = need(r"coreset of (\d+) of (\d+) blocks in ([\d.]+)s .*coding ([\d.]+)s", log,
                 "the K-SVD line")
        row["coreset"], row["blocks"] = int(m.group(1)), int(m.group(2))
        row["train_s"], row["code_s"] = float(m.group(3)), float(m.group(4))
        stored = need(r"PSNR ([\d.]+) dB", log, "the PSNR line")
        if abs(float(stored.group(1)) - row["psnr"]) > 0.02:
            sys.exit("ksvd's stored PSNR %s differs from the measured %.2f" %
                     (stored.group(1), row["psnr"]))
    show(row)
    return row


def ksvd_runs(voxwall, work, name, a, table2, targets, m4_targets, coresets):
    rows = []
    for setting in table2:  # "M6 S8"
        m, s = re.match(r"M(\d+) S(\d+)", setting).groups()
        rows.append(voxwall_run(voxwall, work, name, a, "ksvd", setting,
                                ["--block", m, "--sparsity", s, "--atoms", "1024"] + FLAT))
    for block, values in ((6, targets), (4, m4_targets)):
        for bpv in values:
            rows.append(voxwall_run(voxwall, work, name, a, "ksvd", "M%d target %g" % (block, bpv),
                                    ["--block", str(block), "--bits-per-voxel", str(bpv)] + FLAT,
                                    method="ksvd M%d" % block))
    # The multiresolution pyramid (render --lod), on by default: what it adds to the file.
    rows.append(voxwall_run(voxwall, work, name, a, "ksvd", "M6 S8 pyramid",
                            ["--sparsity", "8", "--atoms", "1024"], method="ksvd pyramid"))
    for fraction in coresets:
        rows.append(voxwall_run(voxwall, work, name, a, "ksvd", "M6 S8 coreset %g" % fraction,
                                ["--sparsity", "8", "--atoms", "1024", "--coreset",
                                 str(fraction)] + FLAT, method="ksvd coreset"))
    return [r for r in rows if r]


def peer_runs(voxwall, work, name, a, reductions):
    rows = []
    if a.dtype == np.float32:
        return rows  # vq and svmm refuse float32
    # vq at fixed reductions (its --bits-per-voxel search runs k-means many times: minutes each)
    for k in reductions:
        rows.append(voxwall_run(voxwall, work, name, a, "vq", "1/%d" % k,
                                ["--reduction", str(k)]))
    for quality in (60, 80, 90):
        rows.append(voxwall_run(voxwall, work, name, a, "svmm", "quality %d" % quality,
                                ["--quality", str(quality)]))
    return rows


# ---- ZFP ----------------------------------------------------------------------------------

def zfp_runs(work, name, a, rates, precisions):
    z, y, x = a.shape
    src = os.path.join(work, name + ".f32")
    a.astype(np.float32).tofile(src)
    rows = []
    for mode, values in (("fixed-rate", rates), ("fixed-precision", precisions)):
        for v in values:
            comp = os.path.join(work, "%s-zfp-%s-%g.zfp" % (name, mode, v))
            dec = comp + ".raw"
            flag = ["-r", str(v)] if mode == "fixed-rate" else ["-p", str(int(v))]
            _, seconds = run(["/usr/bin/time", "-f", "peak %M KiB", "-o", comp + ".mem", "zfp",
                              "-q", "-f", "-3", str(x), str(y), str(z)] + flag +
                             ["-i", src, "-z", comp, "-o", dec])
            with open(comp + ".mem") as f:
                peak = float(need(r"peak (\d+) KiB", f.read(), "zfp's peak memory").group(1)) / 1024
            b = np.fromfile(dec, np.float32).reshape(a.shape)
            if a.dtype != np.float32:  # rounded and clamped to the input's range, as the codec
                b = np.clip(np.rint(b), float(a.min()), float(a.max()))
            row = {"method": "zfp " + mode, "setting": ("rate %g" if mode == "fixed-rate"
                                                        else "precision %g") % v,
                   "bpv": 8.0 * os.path.getsize(comp) / a.size, "psnr": psnr(a, b),
                   "seconds": seconds, "peak_mib": peak, "max_err": max_error(a, b)}
            rows.append(row)
            show(row)
            os.remove(dec)
    os.remove(src)
    return rows


# ---- decode and render speed --------------------------------------------------------------

def speed(bench, raw_vwz, rows, threads):
    files = [raw_vwz] + [r["file"] for r in rows]
    out, _ = run([bench, "--threads", str(threads), "--frames", "2"] + files)
    lines = [l for l in out.splitlines() if l.startswith("| ") and not l.startswith("| volume")]
    if len(lines) != len(files):
        sys.exit("cannot parse voxwall_bench_vq's table:\n" + out)
    result = []
    for line, path in zip(lines, files):
        cells = [c.strip() for c in line.strip("|").split("|")]
        try:
            result.append({"file": os.path.basename(path), "bpv": float(cells[1]),
                           "decode": float(cells[2]), "frame_ms": float(cells[4]),
                           "shaded_ms": float(cells[5])})
        except (ValueError, IndexError):
            sys.exit("cannot parse voxwall_bench_vq's line: " + line)
    return result


# ---- report -------------------------------------------------------------------------------

def table(name, rows):
    print("\n### %s\n" % name)
    print("| method | setting | bits/voxel | PSNR dB | max error | encode s | K-SVD train s | "
          "peak MiB |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print("| %s | %s | %.3f | %s | %.4g | %.1f | %s | %.0f |" % (
            r["method"], r["setting"], r["bpv"],
            "lossless" if r["psnr"] == float("inf") else "%.2f" % r["psnr"], r["max_err"],
            r["seconds"], "%.1f" % r["train_s"] if "train_s" in r else "", r["peak_mib"]))


def speed_table(name, result):
    raw = result[0]
    print("\n### %s: decode and 1920x1080 frames (voxwall_bench_vq, one run)\n" % name)
    print("| file | bits/voxel | decode Mvox/s/core | frame ms | shaded ms | frame / raw | "
          "shaded / raw |")
    print("|---|---|---|---|---|---|---|")
    for r in result:
        print("| %s | %.3f | %.0f | %.0f | %.0f | %.2f | %.2f |" % (
            r["file"], r["bpv"], r["decode"], r["frame_ms"], r["shaded_ms"],
            r["frame_ms"] / raw["frame_ms"], r["shaded_ms"] / raw["shaded_ms"]))



def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--voxwall", default="build/master/voxwall")
    p.add_argument("--bench", default="build/bench/voxwall_bench_vq")
    p.add_argument("--out", default="bench-out/ksvd")
    p.add_argument("--volumes", default="mri,float")
    p.add_argument("--table2", default="M4 S16,M6 S8,M6 S4,M8 S4")
    p.add_argument("--targets", default="0.15,0.25,0.5,1")
    p.add_argument("--m4-targets", default="0.25,0.5,1")
    p.add_argument("--coresets", default="0.01,0.05,0.25,1", help="on the first volume only")
    p.add_argument("--vq-reductions", default="16,64,512")
    p.add_argument("--zfp-rates", default="0.5,1,2")
    p.add_argument("--zfp-precisions", default="6,8,10")
    p.add_argument("--threads", type=int, default=0)
    args = p.parse_args()
    os.makedirs(args.out, exist_ok=True)
    split = lambda s: [v for v in s.split(",") if v]
    targets = [float(v) for v in split(args.targets)]
    results = {}
    coresets = [float(v) for v in split(args.coresets)]
    for name, a in make_inputs(args.voxwall, args.out, split(args.volumes)):
        print("== %s: %dx%dx%d %s" % (name, a.shape[2], a.shape[1], a.shape[0], a.dtype),
              flush=True)
        ksvd = ksvd_runs(args.voxwall, args.out, name, a, split(args.table2), targets,
                         [float(v) for v in split(args.m4_targets)], coresets)
        coresets = []
        rows = ksvd + peer_runs(args.voxwall, args.out, name, a,
                                [int(v) for v in split(args.vq_reductions)])
        rows += zfp_runs(args.out, name, a, [float(v) for v in split(args.zfp_rates)],
                         [float(v) for v in split(args.zfp_precisions)])
        raw_vwz = voxwall_run(args.voxwall, args.out, name, a, "raw", "lossless", [])["file"]
        results[name] = {"rows": rows,
                         "speed": speed(args.bench, raw_vwz,
                                        [r for r in ksvd if r["method"] != "ksvd coreset"],
                                        args.threads)}
        table(name, rows)
        speed_table(name, results[name]["speed"])
        plot(os.path.join(args.out, "rd-%s.png" % name),
             "rate-distortion: %s (ksvd: M S settings as points)" % name, rows,
             points=("ksvd", "ksvd coreset"))
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    print("\nwrote %s/results.json and rd-*.png" % args.out)


if __name__ == "__main__":
    main()
