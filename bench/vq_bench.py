#!/usr/bin/python3
"""Rate-distortion of the vq codec against ZFP and ASTC 3D on the same volumes, in one run.

For every volume: voxwall vq lossless and with reductions 1/2 ... 1/1024 (compressed and plain
codebook), ZFP fixed-rate (zfp CLI, float32 input), ASTC 3D (astcenc, 3x3x3 ... 6x6x6 blocks; LDR
for 8-bit data, HDR with half-float input for 12-bit data). Every method's output is decoded
and compared with the input by the same PSNR (peak = the input's value range, as
voxwall::codec::psnr). Prints a table per volume, writes results.json and rd-<volume>.png.

Run from the repository root after building: /usr/bin/python3 bench/vq_bench.py
(Debian's python3 with numpy and matplotlib; see docs/platform.md.)
"""
import argparse
import json
import os
import re
import struct
import subprocess
import sys
import time

import numpy as np

from rd_common import plot, psnr

MRI = "/usr/share/mricron/templates/ch2better.nii.gz"


def run(cmd, **kw):
    start = time.perf_counter()
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **kw)
    if r.returncode != 0:
        sys.exit("failed: %s\n%s" % (" ".join(cmd), r.stdout))
    return r.stdout, time.perf_counter() - start


# ---- inputs -------------------------------------------------------------------------------

def make_inputs(voxwall, work, which):
    """Returns [(name, array (z, y, x), bits)]."""
    out = []
    if "mri" in which:
        vwz = os.path.join(work, "mri-raw.vwz")
        raw = os.path.join(work, "mri.raw")
        run([voxwall, "compress", MRI, "-o", vwz, "-q"])
        run([voxwall, "decompress", vwz, "-o", raw])
        a = np.fromfile(raw, np.uint8).reshape(316, 370, 301)
        out.append(("ch2better", a, 8))
    if "ct12" in which:
        # A synthetic 12-bit CT-like volume: the 3D Shepp-Logan phantom scaled to 0..4095 with
        # smooth low-amplitude noise (a piecewise-constant phantom alone would flatter every codec).
        n = 192
        raw16 = os.path.join(work, "sl16.raw")
        run([voxwall, "generate", "shepp-logan", "--size", str(n), "--type", "uint16", "-o", raw16])
        a = np.fromfile(raw16, np.uint16).reshape(n, n, n).astype(np.float64) * (3000.0 / 65535.0)
        rng = np.random.default_rng(12)
        noise = rng.normal(0.0, 1.0, a.shape)
        for axis in range(3):  # smooth the noise over ~3 voxels
            noise = (np.roll(noise, 1, axis) + 2 * noise + np.roll(noise, -1, axis)) / 4
        a = np.clip(a + 500.0 * (a > 10) + 40.0 * noise, 0, 4095).astype(np.uint16)
        out.append(("ct12-phantom", a, 12))
    return out


# ---- voxwall vq ---------------------------------------------------------------------------

def vq_runs(voxwall, work, name, a, bits, reductions, codebooks):
    z, y, x = a.shape
    typ = "uint8" if a.dtype == np.uint8 else "uint16"
    src = os.path.join(work, name + ".raw")
    a.tofile(src)
    rows = []
    for codebook in codebooks:
        for k in reductions:
            vwz = os.path.join(work, "%s-vq-%s-%d.vwz" % (name, codebook, k))
            dec = vwz + ".raw"
            cmd = [voxwall, "compress", src, "--dims", "%d,%d,%d" % (x, y, z), "--type", typ,
                   "--codec", "vq", "--codebook", codebook, "--reduction", str(k), "-q", "-o", vwz]
            log, seconds = run(cmd)
            run([voxwall, "decompress", vwz, "-o", dec])
            b = np.fromfile(dec, a.dtype).reshape(a.shape)
            m = re.search(r"(\d+) bricks, (\d+) unique, (\d+) codewords", log)
            skip = re.search(r"([\d.e+]+) distances computed, ([\d.e+]+) skipped.*?(\d+)x fewer", log)
            row = {"method": "vq " + codebook, "setting": "lossless" if k == 1 else "1/%d" % k,
                   "bpv": 8.0 * os.path.getsize(vwz) / a.size, "psnr": psnr(a, b),
                   "seconds": seconds, "codewords": int(m.group(3)) if m else None,
                   "unique": int(m.group(2)) if m else None}
            if skip:
                row["kmeans"] = "%s computed, %s skipped, %sx fewer than plain" % skip.groups()
            rows.append(row)
            print("  %-16s %-9s %7.3f bpv %7.2f dB %7.1f s" % (row["method"], row["setting"],
                  row["bpv"], row["psnr"], seconds), flush=True)
            os.remove(dec)
    return rows


# ---- ZFP ----------------------------------------------------------------------------------

def zfp_runs(work, name, a, rates):
    """ZFP fixed rate on the data as float32 (1-2 dB better than zfp's int32 path on this data,
    checked on ch2better); decoded values are rounded and clipped to the data's range, as a
    reader of integer data would."""
    z, y, x = a.shape
    src = os.path.join(work, name + ".f32")
    a.astype(np.float32).tofile(src)
    rows = []
    for rate in rates:
        comp = os.path.join(work, "%s-%g.zfp" % (name, rate))
        dec = comp + ".raw"
        _, seconds = run(["zfp", "-q", "-f", "-3", str(x), str(y), str(z), "-r", str(rate),
                          "-i", src, "-z", comp, "-o", dec])
        b = np.fromfile(dec, np.float32).reshape(a.shape)
        b = np.clip(np.rint(b), 0, np.iinfo(a.dtype).max)
        rows.append({"method": "zfp fixed-rate", "setting": "rate %g" % rate,
                     "bpv": 8.0 * os.path.getsize(comp) / a.size, "psnr": psnr(a, b),
                     "seconds": seconds})
        print("  %-16s %-9s %7.3f bpv %7.2f dB %7.1f s" % (rows[-1]["method"],
              rows[-1]["setting"], rows[-1]["bpv"], rows[-1]["psnr"], seconds), flush=True)
        os.remove(dec)
    os.remove(src)
    return rows


# ---- ASTC 3D ------------------------------------------------------------------------------

KTX_ID = bytes([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x31, 0x31, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A])


def write_ktx(path, a, half):
    """A KTX 1 file of one 3D texture, one channel (R8 or R16F), rows tightly packed."""
    z, y, x = a.shape
    if half:
        data = a.astype(np.float16).tobytes()
        gl_type, type_size, internal = 0x140B, 2, 0x822D  # GL_HALF_FLOAT, GL_R16F
    else:
        data = a.astype(np.uint8).tobytes()
        gl_type, type_size, internal = 0x1401, 1, 0x8229  # GL_UNSIGNED_BYTE, GL_R8
    header = KTX_ID + struct.pack("<13I", 0x04030201, gl_type, type_size, 0x1903, internal,
                                  0x1903, x, y, z, 0, 1, 1, 0)
    with open(path, "wb") as f:
        f.write(header + struct.pack("<I", len(data)) + data)


def read_ktx(path, shape):
    """First channel of a decoded KTX 1 file (RGBA8 or RGBA16F) as float64."""
    with open(path, "rb") as f:
        blob = f.read()
    (_, gl_type, _, gl_format, _, _, x, y, z, _, _, _, kv) = struct.unpack_from("<13I", blob, 12)
    at = 64 + kv + 4
    channels = {0x1903: 1, 0x8227: 2, 0x1907: 3, 0x1908: 4}[gl_format]
    dtype = {0x1401: np.uint8, 0x140B: np.float16}[gl_type]
    n = shape[0] * shape[1] * shape[2] * channels
    v = np.frombuffer(blob, dtype, count=n, offset=at).reshape(shape + (channels,))
    return v[..., 0].astype(np.float64)


def astc_runs(work, name, a, bits, blocks, preset):
    half = bits > 8
    scale = 4095.0 if half else 1.0
    src = os.path.join(work, name + ".ktx")
    write_ktx(src, a / scale if half else a, half)
    rows = []
    for block in blocks:
        comp = os.path.join(work, "%s-%s.astc" % (name, block))
        dec = comp + ".ktx"
        mode_c, mode_d = ("-ch", "-dh") if half else ("-cl", "-dl")
        _, seconds = run(["astcenc", mode_c, src, comp, block, preset, "-esw", "rrr1", "-silent"])
        run(["astcenc", mode_d, comp, dec, "-silent"])
        b = np.clip(np.rint(read_ktx(dec, a.shape) * scale), 0, np.iinfo(a.dtype).max)
        rows.append({"method": "astc 3d " + ("hdr" if half else "ldr"), "setting": block,
                     "bpv": 8.0 * os.path.getsize(comp) / a.size, "psnr": psnr(a, b),
                     "seconds": seconds})
        print("  %-16s %-9s %7.3f bpv %7.2f dB %7.1f s" % (rows[-1]["method"],
              rows[-1]["setting"], rows[-1]["bpv"], rows[-1]["psnr"], seconds), flush=True)
        os.remove(dec)
    return rows


# ---- report -------------------------------------------------------------------------------

def table(name, rows):
    print("\n### %s\n" % name)
    print("| method | setting | bits/voxel | PSNR dB | encode s |")
    print("|---|---|---|---|---|")
    for r in rows:
        print("| %s | %s | %.3f | %s | %.1f |" % (r["method"], r["setting"], r["bpv"],
              "lossless" if r["psnr"] == float("inf") else "%.2f" % r["psnr"], r["seconds"]))



def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--voxwall", default="build/master/voxwall")
    p.add_argument("--out", default="bench-out/vq")
    p.add_argument("--volumes", default="mri,ct12")
    p.add_argument("--reductions", default="1,2,4,8,16,32,64,128,256,512,1024")
    p.add_argument("--codebooks", default="compressed,plain")
    p.add_argument("--zfp-rates", default="0.25,0.5,1,2,4")
    p.add_argument("--astc-blocks", default="3x3x3,4x4x4,5x5x5,6x6x6")
    p.add_argument("--astc-preset", default="-medium")
    args = p.parse_args()
    os.makedirs(args.out, exist_ok=True)
    reductions = [int(k) for k in args.reductions.split(",")]
    results = {}
    for name, a, bits in make_inputs(args.voxwall, args.out, args.volumes.split(",")):
        print("== %s: %dx%dx%d, %d-bit" % (name, a.shape[2], a.shape[1], a.shape[0], bits),
              flush=True)
        rows = vq_runs(args.voxwall, args.out, name, a, bits, reductions,
                       args.codebooks.split(","))
        rows += zfp_runs(args.out, name, a, [float(r) for r in args.zfp_rates.split(",")])
        rows += astc_runs(args.out, name, a, bits, args.astc_blocks.split(","), args.astc_preset)
        results[name] = rows
        table(name, rows)
        plot(os.path.join(args.out, "rd-%s.png" % name), "rate-distortion: " + name, rows)
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    print("\nwrote %s/results.json and rd-*.png" % args.out)


if __name__ == "__main__":
    main()
