#!/usr/bin/python3
"""Pictures of compressed volumes against the raw data's: every codec at size targets.

For each volume (the MRI template ch2better, the MRI at 1 mm ch2, the MRI as float32 with smooth
noise, and a CT-like int16 phantom in Hounsfield units, as in ksvd_bench.py and zfp_bench.py) and
each size target (0.25, 0.5 and 1 bits per voxel by default), every codec that takes a size
target (vq, ksvd with one level, tvq, zfp; vq refuses float32) is asked for that size, and the
zfp command line runs at the same rate (fixed rate on the whole volume; its output rounded and
clamped to the input's range as the codec does, then stored raw). Each file is decoded and
compared with the input (volume PSNR, peak = the input's value range, as voxwall's psnr), and
rendered at 960x540 with `--exact` and the default transfer function (stretched over the input's
value range for every file) from three fixed cameras,
unshaded and shaded; each picture is compared with the raw volume's picture of the same camera
by the PSNR of its RGB channels (peak 255). With --compare, a second voxwall (an earlier build)
makes and renders its own files of the same codecs in the same run, for a before/after table.
Writes, for the best codec at 0.5 bits per voxel on each volume, its shaded picture and a
difference picture (|raw - codec| x 8) from the first camera.

Prints a table per volume and writes results.json into --out.

Run from the repository root after building: /usr/bin/python3 bench/picture_quality_bench.py
(Debian's python3 with numpy and python3-pil; scripts/install-deps.sh bench installs zfp).
A full run (four volumes, three rates, five codecs, two builds) takes hours on 2 cores, mostly
vq's and tvq's codebook training: --volumes, --rates and --codecs pick a part.
"""
import argparse
import json
import os
import shutil
import sys
import tempfile

import numpy as np

from frames_common import load_rgba
from ksvd_bench import (MRI, REFUSED, ct_phantom, max_error, need, run, save_raw)
from rd_common import psnr

MRI_1MM = "/usr/share/mricron/templates/ch2.nii.gz"
CAMERAS = ["30,20", "-90,0", "150,45"]
SIZE = "960x540"


def mri(voxwall, work, path, name):
    vwz = os.path.join(work, name + "-in.vwz")
    raw = os.path.join(work, name + "-in.raw")
    run([voxwall, "compress", path, "-o", vwz, "-q"])
    info, _ = run([voxwall, "info", vwz])
    m = need(r"dims\s+(\d+) x (\d+) x (\d+)", info, "the volume's dims")
    x, y, z = (int(v) for v in m.groups())
    run([voxwall, "decompress", vwz, "-o", raw])
    a = np.fromfile(raw, np.uint8).reshape(z, y, x)
    os.remove(raw)
    os.remove(vwz)
    return a


def inputs(voxwall, work, which):
    """[(name, array (z, y, x))] for the volumes asked for."""
    out = []
    template = None
    if "mri" in which or "float" in which:
        template = mri(voxwall, work, MRI, "ch2better")
    if "mri" in which:
        out.append(("ch2better", template))
    if "mri1mm" in which:
        out.append(("ch2-1mm", mri(voxwall, work, MRI_1MM, "ch2")))
    if "float" in which:  # the MRI as float32 with smooth noise of 1% of the range
        rng = np.random.default_rng(7)
        noise = rng.normal(0.0, 1.0, template.shape)
        for axis in range(3):
            noise = (np.roll(noise, 1, axis) + 2 * noise + np.roll(noise, -1, axis)) / 4
        out.append(("mri-float32",
                    (template.astype(np.float64) / 255.0 + 0.01 * noise).astype(np.float32)))
    if "ct" in which:
        out.append(("ct-phantom-int16", ct_phantom(voxwall, work)))
    return out


def render(voxwall, vwz, folder, value_range):
    """The six pictures of a file (three cameras, unshaded and shaded): {key: RGB array}. The
    transfer function is stretched over the input's value range, whatever the file's (the zfp
    command line's output has a range of its own)."""
    pictures = {}
    for cam in CAMERAS:
        for shaded in (False, True):
            d = os.path.join(folder, "%s%s" % (cam.replace(",", "_"), "-shaded" if shaded else ""))
            shutil.rmtree(d, ignore_errors=True)
            run([voxwall, "render", vwz, "--size", SIZE, "--frames", "1", "--camera", cam,
                 "--exact", "--tf-range", "%r,%r" % value_range, "--out", d, "-q"] +
                (["--shading"] if shaded else []))
            frame = os.path.join(d, "frame_00000.png")
            if not os.path.exists(frame):
                sys.exit("picture_quality_bench: %s rendered no %s" % (vwz, frame))
            pictures[(cam, shaded)] = load_rgba(frame, "picture_quality_bench")[..., :3]
    return pictures


def picture_psnr(ref, test):
    mse = float(np.mean((ref - test) ** 2))
    if mse == 0:
        return 99.0
    return 10 * np.log10(255.0 ** 2 / mse)


def compress(voxwall, work, name, a, codec, bpv, tag):
    """A file of `codec` at `bpv`; None (and the refusal printed) when the codec refuses."""
    src, fmt = save_raw(work, name, a)
    vwz = os.path.join(work, "%s-%s-%g-%s.vwz" % (name, codec, bpv, tag))
    extra = ["--levels", "1"] if codec == "ksvd" else []
    log, why = run([voxwall, "compress", src] + fmt + ["--codec", codec, "--bits-per-voxel",
                                                        str(bpv)] + extra + ["-o", vwz],
                   refusal=REFUSED + ("are not supported",))
    if log is None:
        print("  %-14s %-6s %5g bpv refused: %s" % (codec, tag, bpv, why), flush=True)
        return None
    dec = vwz + ".raw"
    run([voxwall, "decompress", vwz, "-o", dec])
    b = np.fromfile(dec, a.dtype).reshape(a.shape)
    os.remove(dec)
    return vwz, b


def zfp_cli(voxwall, work, name, a, bpv):
    """The zfp command line in fixed rate `bpv`, its output stored raw (rounded and clamped to the
    input's range for integer data)."""
    z, y, x = a.shape
    src = os.path.join(work, name + ".f32")
    a.astype(np.float32).tofile(src)
    comp = os.path.join(work, "%s-zfpcli-%g.zfp" % (name, bpv))
    dec = comp + ".raw"
    run(["zfp", "-q", "-f", "-3", str(x), str(y), str(z), "-r", str(bpv), "-i", src, "-z", comp,
         "-o", dec])
    b = np.fromfile(dec, np.float32).reshape(a.shape)
    if a.dtype != np.float32:
        b = np.clip(np.rint(b), float(a.min()), float(a.max()))
    b = b.astype(a.dtype)
    size = os.path.getsize(comp)
    for f in (src, comp, dec):
        os.remove(f)
    raw, fmt = save_raw(work, name + "-zfpcli-dec", b)
    vwz = os.path.join(work, "%s-zfpcli-%g.vwz" % (name, bpv))
    run([voxwall, "compress", raw] + fmt + ["-o", vwz, "-q"])
    os.remove(raw)
    return vwz, b, 8.0 * size / a.size


def row_of(method, bpv, a, b, pictures, reference):
    shaded = [picture_psnr(reference[(c, True)], pictures[(c, True)]) for c in CAMERAS]
    flat = [picture_psnr(reference[(c, False)], pictures[(c, False)]) for c in CAMERAS]
    row = {"method": method, "bpv": bpv, "psnr": psnr(a, b), "max_err": max_error(a, b),
           "unshaded": flat, "shaded": shaded}
    print("  %-18s %6.3f bpv  volume %6.2f dB  pictures unshaded %s  shaded %s" % (
        method, bpv, row["psnr"], " ".join("%.2f" % v for v in flat),
        " ".join("%.2f" % v for v in shaded)), flush=True)
    return row


def table(name, rows, rates):
    print("\n%s: PSNR of the volume and of its pictures against the raw data's (dB; pictures: "
          "mean of 3 cameras, RGB, %s, --exact)" % (name, SIZE))
    print("| target | method | bits/voxel | volume | unshaded | shaded | shaded, worst camera |")
    print("|---|---|---|---|---|---|---|")
    for rate in rates:
        for r in sorted((r for r in rows if r["target"] == rate), key=lambda r: r["method"]):
            print("| %g | %s | %.3f | %.2f | %.2f | %.2f | %.2f |" % (
                rate, r["method"], r["bpv"], r["psnr"], np.mean(r["unshaded"]),
                np.mean(r["shaded"]), min(r["shaded"])))


def difference(out, name, reference, rows, voxwall, work, value_range):
    """The best row at 0.5 bits per voxel: its shaded picture and |raw - it| x 8, first camera."""
    from PIL import Image
    half = [r for r in rows if r["target"] == 0.5 and "file" in r]
    if not half:
        return
    best = max(half, key=lambda r: np.mean(r["shaded"]))
    pics = render(voxwall, best["file"], os.path.join(work, "best"), value_range)
    key = (CAMERAS[0], True)
    diff = np.clip(np.abs(reference[key] - pics[key]) * 8, 0, 255).astype(np.uint8)
    Image.fromarray(pics[key].astype(np.uint8)).save(os.path.join(out, "%s-best.png" % name))
    Image.fromarray(diff).save(os.path.join(out, "%s-difference.png" % name))
    print("  best at 0.5 bits per voxel: %s; wrote %s-best.png and %s-difference.png" % (
        best["method"], name, name))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--voxwall", default="build/master/voxwall")
    p.add_argument("--compare", help="an earlier voxwall: its files of the same codecs beside")
    p.add_argument("--volumes", default="mri,mri1mm,float,ct",
                   help="comma-separated: mri, mri1mm, float, ct")
    p.add_argument("--rates", default="0.25,0.5,1")
    p.add_argument("--codecs", default="vq,ksvd,tvq,zfp,zfp-cli")
    p.add_argument("--compare-codecs", default="ksvd",
                   help="the codecs --compare's voxwall makes files of (default: ksvd)")
    p.add_argument("--out", default="bench-results/picture-quality")
    args = p.parse_args()
    rates = [float(v) for v in args.rates.split(",")]
    codecs = args.codecs.split(",")
    os.makedirs(args.out, exist_ok=True)
    results = {}
    with tempfile.TemporaryDirectory(prefix="voxwall-pictures-") as work:
        for name, a in inputs(args.voxwall, work, args.volumes.split(",")):
            print("\n== %s %s %s" % (name, "x".join(str(v) for v in a.shape[::-1]), a.dtype),
                  flush=True)
            src, fmt = save_raw(work, name, a)
            raw_vwz = os.path.join(work, name + "-raw.vwz")
            run([args.voxwall, "compress", src] + fmt + ["-o", raw_vwz, "-q"])
            value_range = (float(a.min()), float(a.max()))
            reference = render(args.voxwall, raw_vwz, os.path.join(work, "raw"), value_range)
            rows = []
            builds = [(args.voxwall, "", codecs)]
            if args.compare:
                builds.append((args.compare, "before", args.compare_codecs.split(",")))
            for rate in rates:
                for voxwall, tag, which in builds:
                    for codec in which:
                        if codec == "zfp-cli":
                            vwz, b, bpv = zfp_cli(args.voxwall, work, name, a, rate)
                            method = "zfp command line"
                        else:
                            made = compress(voxwall, work, name, a, codec, rate, tag or "now")
                            if made is None:
                                continue
                            vwz, b = made
                            bpv = 8.0 * os.path.getsize(vwz) / a.size
                            method = codec + (" (%s)" % tag if tag else "")
                        pictures = render(voxwall, vwz, os.path.join(work, "pictures"),
                                          value_range)
                        row = row_of(method, bpv, a, b, pictures, reference)
                        row["target"] = rate
                        if not tag and codec != "zfp-cli":
                            row["file"] = vwz
                        rows.append(row)
            table(name, rows, rates)
            difference(args.out, name, reference, rows, args.voxwall, work, value_range)
            for r in rows:
                r.pop("file", None)
            for f in os.listdir(work):  # this volume's files
                if f.startswith(name) and f.endswith(".vwz"):
                    os.remove(os.path.join(work, f))
            results[name] = rows
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    print("\nwrote %s/results.json" % args.out)


if __name__ == "__main__":
    main()
