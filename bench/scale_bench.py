#!/usr/bin/python3
"""Big volumes: what each codec costs on a volume of about a gigavoxel, in one run.

The volume is the MRI template (mricron-data) upsampled --scale times per axis (3: 903x1110x948,
0.95 Gvox of uint8; trilinear, with mild Gaussian noise of sigma 1.5 so that no two bricks are
alike), generated here into the work directory and never kept. Each codec compresses it once
(`voxwall compress` under /usr/bin/time -v: wall time and peak resident memory), then every file
is rendered the same way: --frames 3 of one still view at --size, shaded, one rank, with
`render -v`, which prints each frame's time and the decoded-page cache's hits, pages decoded
and evictions. Frames 2 and 3 are the ones compared (the first decodes the pages its rays reach): the mean of the two, and each
codec's over raw's from the same run. Per-rank resident memory comes from the render's own
totals (`rank N on HOST: resident ..., peak ...`), at 1, 2 and 4 ranks under mpirun (strip cut,
--balance static) for --rank-codecs. The page cache is measured at --budgets for --budget-codecs.

Then a float32 volume (the same MRI at --float-scale, values not rounded) is compressed with
--float-codecs and rendered the same way, and a generated volume (shepp-logan --limit-size^3) is
compressed under a data limit of a third of its size (prlimit --data).

Prints markdown tables. Stops with an error when a run fails or prints something it cannot
parse. Needs the bench dependencies (scripts/install-deps.sh bench: numpy, time, Open MPI) and
a release build. Takes about an hour on a 2-core VM at --scale 3; --scale 1 is the MRI itself
(for a quick check of the script).

Run from the repository root: /usr/bin/python3 bench/scale_bench.py [--scale 3]
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile

import numpy as np

MRI = "/usr/share/mricron/templates/ch2better.nii.gz"
FRAME = re.compile(r"^frame (\d+)/\d+: ([0-9.]+) ms", re.M)
PAGES = re.compile(r"decoded pages: ([0-9.]+)% hits \((\d+) of (\d+) samples\), (\d+) decoded, "
                   r"(\d+) evicted, ([0-9.]+ [KMGT]?i?B|\d+ B) resident"
                   r"(?:, (\d+) samples from coarser levels)?")
RESIDENT = re.compile(r"^rank (\d+) on \S+: resident ([0-9.]+ [KMGT]?i?B|\d+ B), peak "
                      r"([0-9.]+ [KMGT]?i?B|\d+ B)", re.M)
UNITS = {"B": 1, "KiB": 1 << 10, "MiB": 1 << 20, "GiB": 1 << 30, "TiB": 1 << 40}
# svmm lossless takes more bits than the noisy volume's 8: compress refuses that unless told
# --allow-larger, which keeps the file the tables have always measured.
OPTIONS = {"raw": [], "vq": [], "svmm": ["--quality", "100", "--allow-larger"], "ksvd": [], "tvq": [], "zfp": []}


def run(cmd, env=None):
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    if r.returncode != 0:
        sys.exit("failed: %s\n%s" % (" ".join(cmd), r.stdout[-4000:]))
    return r.stdout


def size_bytes(text):
    number, unit = text.split()
    if unit not in UNITS:
        sys.exit("cannot read the size %r" % text)
    return float(number) * UNITS[unit]


def mib(b):
    return "%.0f MiB" % (b / (1 << 20))


def generate(voxwall, scale, work, dtype=np.uint8):
    """The MRI upsampled `scale` times per axis with mild noise, as a .raw file of uint8 (rounded)
    or float32 (not rounded); its dims."""
    small = os.path.join(work, "mri.raw")
    vwz = os.path.join(work, "mri.vwz")
    run([voxwall, "compress", MRI, "--codec", "raw", "-q", "-o", vwz])
    info = run([voxwall, "info", vwz])
    m = re.search(r"^dims\s+(\d+) x (\d+) x (\d+) ", info, re.M)
    if not m:
        sys.exit("cannot find the MRI's dims in:\n" + info)
    dims = [int(m.group(i)) for i in (1, 2, 3)]
    run([voxwall, "decompress", vwz, "-o", small])
    os.remove(vwz)
    src = np.fromfile(small, dtype=np.uint8).reshape(dims[2], dims[1], dims[0])
    os.remove(small)
    out_dims = [int(round(d * scale)) for d in dims]
    path = os.path.join(work, "big-%s.raw" % np.dtype(dtype).name)
    out = np.lib.format.open_memmap(path + ".npy", mode="w+", dtype=dtype,
                                    shape=(out_dims[2], out_dims[1], out_dims[0]))
    # Trilinear: positions (i + 0.5) / scale - 0.5 in the source, per axis.
    def axis(n_out, n_in):
        p = np.clip((np.arange(n_out) + 0.5) / scale - 0.5, 0, n_in - 1)
        i0 = np.floor(p).astype(np.int64)
        i1 = np.minimum(i0 + 1, n_in - 1)
        return i0, i1, (p - i0).astype(np.float32)
    x0, x1, tx = axis(out_dims[0], dims[0])
    y0, y1, ty = axis(out_dims[1], dims[1])
    z0, z1, tz = axis(out_dims[2], dims[2])
    rng = np.random.default_rng(7)
    srcf = src.astype(np.float32)
    for z in range(out_dims[2]):
        plane = srcf[z0[z]] * (1 - tz[z]) + srcf[z1[z]] * tz[z]
        rows = plane[y0] * (1 - ty)[:, None] + plane[y1] * ty[:, None]
        vals = rows[:, x0] * (1 - tx)[None, :] + rows[:, x1] * tx[None, :]
        vals += rng.normal(0.0, 1.5, vals.shape).astype(np.float32)
        if dtype == np.uint8:
            out[z] = np.clip(np.rint(vals), 0, 255).astype(np.uint8)
        else:
            out[z] = vals
    out.flush()
    del out
    # The voxels follow the .npy's header.
    with open(path + ".npy", "rb") as f:
        if np.lib.format.read_magic(f) == (1, 0):
            np.lib.format.read_array_header_1_0(f)
        else:
            np.lib.format.read_array_header_2_0(f)
        start = f.tell()
    with open(path + ".npy", "rb") as f, open(path, "wb") as g:
        f.seek(start)
        shutil.copyfileobj(f, g, 64 << 20)
    os.remove(path + ".npy")
    return path, out_dims


def timed(cmd):
    """Runs cmd under /usr/bin/time -v: (output, wall seconds, peak resident bytes)."""
    out = run(["/usr/bin/time", "-v"] + cmd)
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (?:(\d+):)?(\d+):([0-9.]+)",
                     out)
    peak = re.search(r"Maximum resident set size \(kbytes\): (\d+)", out)
    if not wall or not peak:
        sys.exit("cannot read /usr/bin/time's report for %s:\n%s" % (" ".join(cmd), out[-3000:]))
    seconds = int(wall.group(1) or 0) * 3600 + int(wall.group(2)) * 60 + float(wall.group(3))
    return out, seconds, int(peak.group(1)) * 1024


def render(args, path, ranks=1, budget=None, extra=()):
    """One render: (mean ms of frames 2.., per-rank resident bytes, per-frame page lines)."""
    cmd = [args.voxwall, "render", path, "--size", args.size, "--frames", "3", "--shading",
           "--no-write", "-v", "--path", "still", "--camera", "30,20,2.2", "--exact"] + list(extra)
    if budget:
        cmd += ["--decode-cache", budget]
    env = None
    if ranks > 1:
        cmd = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-np", str(ranks)] + cmd + [
            "--balance", "static"]
        env = dict(os.environ, OMPI_MCA_rmaps_base_oversubscribe="1")
    out = run(cmd, env)
    frames = {int(m.group(1)): float(m.group(2)) for m in FRAME.finditer(out)}
    if sorted(frames) != [1, 2, 3]:
        sys.exit("cannot find three frame times in the output of %s:\n%s" % (" ".join(cmd), out))
    resident = {int(m.group(1)): size_bytes(m.group(2)) for m in RESIDENT.finditer(out)}
    if len(resident) != ranks:
        sys.exit("cannot find %d ranks' resident memory in the output of %s:\n%s"
                 % (ranks, " ".join(cmd), out))
    pages = [m.groups() for m in PAGES.finditer(out)]
    return (frames[2] + frames[3]) / 2, resident, pages


def compress_table(args, source, dims, scalar, codecs, files):
    """Compresses `source` with each codec: {codec: (seconds, peak bytes, file bytes)}; prints the
    table."""
    voxels = dims[0] * dims[1] * dims[2]
    input_bytes = voxels * (4 if scalar == "float32" else 1)
    layout = ["--dims", "%d,%d,%d" % tuple(dims), "--type", scalar]
    compress = {}
    for c in codecs:
        print("compressing %s as %s" % (scalar, c), file=sys.stderr)
        _, seconds, peak = timed([args.voxwall, "compress", source, "--codec", c, "-q",
                                  "-o", files[c]] + layout + OPTIONS[c])
        compress[c] = (seconds, peak, os.path.getsize(files[c]))
    print("%dx%dx%d %s (%.2f Gvox, %s)\n" % (dims[0], dims[1], dims[2], scalar, voxels / 1e9,
                                          mib(input_bytes)))
    print("| codec | file | bits/voxel | compress time | compress peak | peak / input |")
    print("|---|---|---|---|---|---|")
    for c in codecs:
        seconds, peak, size = compress[c]
        print("| %s | %s | %.2f | %.0f s | %s | %.2f |"
              % (c, mib(size), 8.0 * size / voxels, seconds, mib(peak), peak / input_bytes))
    print()
    return compress


def pressure_table(args, files, raw_ms):
    """Frames of the codecs with coarser levels at budgets below the view's working set, with and
    without --lod-under-pressure."""
    rows = [(c, b) for c in args.pressure_codecs.split(",") if c in files
            for b in args.pressure_budgets.split(",")]
    if not rows:
        return
    print("Level of detail under pressure (1 rank, still view, frames 2 and 3, over raw's frame "
          "rendered again just before)\n")
    print("| codec | budget | frame / raw | with --lod-under-pressure | samples from coarser "
          "levels (frames 2, 3) | pages decoded (frames 2, 3) |")
    print("|---|---|---|---|---|---|")
    for c, b in rows:
        print("rendering %s with --decode-cache %s, with and without --lod-under-pressure" % (c, b),
              file=sys.stderr)
        plain = render(args, files[c], budget=b)[0]
        ms, _, pages = render(args, files[c], budget=b, extra=["--lod-under-pressure"])
        if len(pages) != 3 or any(p[6] is None for p in pages):
            sys.exit("expected three page lines with coarse samples for %s, got %r" % (c, pages))
        share = ["%.1f%%" % (100.0 * int(p[6]) / int(p[2])) for p in pages[1:]]
        print("| %s | %s | %.2f | %.2f | %s | %s, %s |"
              % (c, b, plain / raw_ms, ms / raw_ms, ", ".join(share), pages[1][3], pages[2][3]))
    print()


def limit_table(args, work):
    """A generated volume --limit-size^3 compressed with vq and svmm under a data limit of a third
    of its size (prlimit --data), and with raw, whose output alone is over the limit."""
    n = args.limit_size
    if n ** 3 // 3 < 256 << 20:
        sys.exit("--limit-size %d is too small: a third of it must leave room for the ~100 MiB of "
                 "data the process has before any voxel (libraries, threads); use 923 or more" % n)
    source = os.path.join(work, "limit.raw")
    run([args.voxwall, "generate", "shepp-logan", "--size", str(n), "-o", source])
    input_bytes = n ** 3
    limit = input_bytes // 3
    print("Compress under a memory limit: shepp-logan %d^3 uint8 (%s), prlimit --data=%s (a third "
          "of the input)\n" % (n, mib(input_bytes), mib(limit)))
    print("| codec | result | compress peak | peak / input |")
    print("|---|---|---|---|")
    for c in ("vq", "svmm", "raw"):
        cmd = ["/usr/bin/time", "-v", "prlimit", "--data=%d" % limit, args.voxwall, "compress",
               source, "--dims", "%d,%d,%d" % (n, n, n), "--type", "uint8", "--codec", c, "-q",
               "-o", os.path.join(work, "limit.vwz")]
        r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        peak = re.search(r"Maximum resident set size \(kbytes\): (\d+)", r.stdout)
        refused = re.search(r"^voxwall: .*not enough memory.*$", r.stdout, re.M)
        if not peak or (r.returncode != 0 and not refused):
            sys.exit("cannot read the limited compress with %s:\n%s" % (c, r.stdout[-3000:]))
        result = "compressed" if r.returncode == 0 else "refused: not enough memory"
        peak_bytes = int(peak.group(1)) * 1024
        print("| %s | %s | %s | %.2f |" % (c, result, mib(peak_bytes), peak_bytes / input_bytes))
    print()
    os.remove(source)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--voxwall", default="build/master/voxwall")
    ap.add_argument("--scale", type=int, default=3)
    ap.add_argument("--size", default="1920x1080")
    ap.add_argument("--codecs", default="raw,vq,svmm,ksvd,tvq,zfp")
    ap.add_argument("--rank-codecs", default="raw,vq,ksvd")
    ap.add_argument("--budget-codecs", default="vq,ksvd")
    ap.add_argument("--budgets", default="32M,128M,512M,64G")
    ap.add_argument("--pressure-codecs", default="svmm,ksvd",
                    help="codecs rendered with and without --lod-under-pressure at "
                         "--pressure-budgets")
    ap.add_argument("--pressure-budgets", default="32M,128M")
    ap.add_argument("--float-scale", type=float, default=2.5,
                    help="the float32 volume: the MRI upsampled this much (2.5: 0.55 Gvox); 0: none")
    ap.add_argument("--float-codecs", default="raw,tvq,ksvd")
    ap.add_argument("--limit-size", type=int, default=1024,
                    help="side of the volume compressed under a memory limit (0: none)")
    ap.add_argument("--keep", help="work directory to use and keep (default: a temporary one)")
    ap.add_argument("--reuse", action="store_true",
                    help="render the .vwz files an earlier run left in --keep (no compress table)")
    args = ap.parse_args()
    if not os.path.exists(MRI):
        sys.exit("needs the MRI template %s (apt-get install mricron-data)" % MRI)
    codecs = args.codecs.split(",")
    for c in codecs:
        if c not in OPTIONS:
            sys.exit("unknown codec %s (expected one of %s)" % (c, ", ".join(OPTIONS)))
    if "raw" not in codecs:
        sys.exit("--codecs must include raw: every frame time is compared with raw's")
    if args.reuse and not args.keep:
        sys.exit("--reuse needs --keep DIR")
    work = args.keep or tempfile.mkdtemp(prefix="voxwall-scale-")
    os.makedirs(work, exist_ok=True)
    try:
        files = {c: os.path.join(work, c + ".vwz") for c in codecs}
        if args.reuse:
            # The files of an earlier run with --keep: no compress table.
            for c in codecs:
                if not os.path.exists(files[c]):
                    sys.exit("--reuse: %s is missing" % files[c])
            m = re.search(r"^dims\s+(\d+) x (\d+) x (\d+) ",
                          run([args.voxwall, "info", files["raw"]]), re.M)
            if not m:
                sys.exit("cannot find the dims of " + files["raw"])
            dims = [int(m.group(i)) for i in (1, 2, 3)]
            compress = {c: (0, 0, os.path.getsize(files[c])) for c in codecs}
        else:
            print("generating the volume (MRI x%d)" % args.scale, file=sys.stderr)
            source, dims = generate(args.voxwall, args.scale, work)
        voxels = dims[0] * dims[1] * dims[2]
        if not args.reuse:
            compress = compress_table(args, source, dims, "uint8", codecs, files)
            os.remove(source)
        print("%dx%dx%d uint8 (%.2f Gvox), %s, shaded, 1 rank, default --decode-cache (512M); "
              "frames 2 and 3\n" % (dims[0], dims[1], dims[2], voxels / 1e9, args.size))
        print("| codec | frame ms | frame / raw | resident | file | page hits "
              "| pages decoded (frames 1, 2, 3) | evicted (frames 2, 3) |")
        print("|---|---|---|---|---|---|---|---|")
        one = {}
        for c in codecs:
            print("rendering %s" % c, file=sys.stderr)
            one[c] = render(args, files[c])
        for c in codecs:
            ms, resident, pages = one[c]
            hits = "%s%%, %s%%" % (pages[1][0], pages[2][0]) if len(pages) == 3 else "-"
            decoded = ", ".join(p[3] for p in pages) if len(pages) == 3 else "-"
            evicted = "%s, %s" % (pages[1][4], pages[2][4]) if len(pages) == 3 else "-"
            print("| %s | %.0f | %.2f | %s | %s | %s | %s | %s |"
                  % (c, ms, ms / one["raw"][0], mib(resident[0]),
                     mib(compress[c][2]), hits, decoded, evicted))
        print()
        rank_codecs = [c for c in args.rank_codecs.split(",") if c in files]
        if rank_codecs:
            print("Resident memory per rank (the largest rank's), strip cut, --balance static\n")
            print("| codec | 1 rank | 2 ranks | 4 ranks | 4 ranks / 1 rank |")
            print("|---|---|---|---|---|")
        for c in rank_codecs:
            per = {1: max(one[c][1].values())}
            for n in (2, 4):
                print("rendering %s on %d ranks" % (c, n), file=sys.stderr)
                per[n] = max(render(args, files[c], ranks=n, extra=["--threads", "1"])[1].values())
            print("| %s | %s | %s | %s | %.2f |"
                  % (c, mib(per[1]), mib(per[2]), mib(per[4]), per[4] / per[1]))
        if rank_codecs:
            print()
        budget_rows = [(c, b) for c in args.budget_codecs.split(",") if c in files
                       for b in args.budgets.split(",")]
        if budget_rows:
            print("Page cache by budget (1 rank): pages decoded by frame 1, then frames 2 and 3 "
                  "(raw rendered again first, for the ratio)\n")
            print("| codec | budget | frame ms | frame / raw | frame 1 decoded | hits | decoded "
                  "| evicted | resident |")
            print("|---|---|---|---|---|---|---|---|---|")
        raw_ms = render(args, files["raw"])[0]
        for c, b in budget_rows:
            print("rendering %s with --decode-cache %s" % (c, b), file=sys.stderr)
            ms, resident, pages = render(args, files[c], budget=b)
            if len(pages) != 3:
                sys.exit("expected three page lines for %s, got %d" % (c, len(pages)))
            print("| %s | %s | %.0f | %.2f | %s | %s%%, %s%% | %s, %s | %s, %s | %s |"
                  % (c, b, ms, ms / raw_ms, pages[0][3], pages[1][0], pages[2][0], pages[1][3],
                     pages[2][3], pages[1][4], pages[2][4], mib(resident[0])))
        if budget_rows:
            print()
        pressure_table(args, files, raw_ms)
        if args.float_scale > 0 and not args.reuse:
            float_codecs = args.float_codecs.split(",")
            if "raw" not in float_codecs:
                sys.exit("--float-codecs must include raw")
            print("generating the float32 volume (MRI x%g)" % args.float_scale, file=sys.stderr)
            fsource, fdims = generate(args.voxwall, args.float_scale, work, np.float32)
            ffiles = {c: os.path.join(work, c + "-float.vwz") for c in float_codecs}
            compress_table(args, fsource, fdims, "float32", float_codecs, ffiles)
            os.remove(fsource)
            print("float32, %s, shaded, 1 rank, default --decode-cache (512M); frames 2 and 3\n"
                  % args.size)
            print("| codec | frame ms | frame / raw | resident | page hits |")
            print("|---|---|---|---|---|")
            fone = {}
            for c in float_codecs:
                print("rendering float32 %s" % c, file=sys.stderr)
                fone[c] = render(args, ffiles[c])
            for c in float_codecs:
                ms, resident, pages = fone[c]
                hits = "%s%%, %s%%" % (pages[1][0], pages[2][0]) if len(pages) == 3 else "-"
                print("| %s | %.0f | %.2f | %s | %s |"
                      % (c, ms, ms / fone["raw"][0], mib(resident[0]), hits))
            print()
            for f in ffiles.values():
                os.remove(f)
        if args.limit_size > 0 and not args.reuse:
            limit_table(args, work)
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
