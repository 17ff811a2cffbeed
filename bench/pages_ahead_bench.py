#!/usr/bin/python3
"""Compressed volumes where pages are new: first frames and camera jumps against raw data.

A frame that meets pages it has not decoded pays for them (docs/rendering.md, "Decoded pages").
This bench renders, for every codec and raw, from the same volume in the same run:

- the first frame and an orbit of 90 degrees a frame (--frames 4 --orbit-deg 90: every frame
  sees the volume from another side), and an orbit of 5 degrees a frame (--frames 6: few pages
  are new), one rank with every core;
- the first frame and the 90-degree orbit on --ranks ranks of one thread each (mpirun, strip
  cut, --balance static), with each rank's own memory: its private memory (decoded pages, frame
  buffers, the heap) plus its share of the memory the ranks on its host share (tables a codec
  makes once for all of them: tvq's associated codebooks; the MPI library's buffers), apart from
  its mapped files (the .vwz, which the ranks on one host share).

Every render is `render --exact --shading --no-write -v` at --size from camera 30,20,2.2; a frame's
time is the whole frame's (`frame N/M: X ms`), and every codec's is given over raw's same frame.
The first picture is the time from the job's start (the volume opened and its value ranges for
skipping empty space made) to the end of its first frame: the 90-degree job's wall clock less
its frames 2-4.
The pages a rank decoded and the samples that waited for a page another thread was decoding come
from `render -v`'s page lines (summed over the ranks).

The volume is scale_bench.py's: the MRI template (mricron-data) upsampled --scale times per axis
with mild noise (1: 301x370x316; 3: 903x1110x948, 0.95 Gvox), generated into a temporary directory
and never kept (or into --work DIR, where the codecs' files are kept and used again by the next
run); each codec compresses it with scale_bench.py's options.

With --compare VOXWALL (an earlier build's program), each ratio is followed by that program's,
in parentheses, from the same files in the same run.

Prints markdown tables. Stops with an error when a run fails or prints something it cannot parse.
Needs a release build (build/), numpy and Open MPI.

Run from the repository root: /usr/bin/python3 bench/pages_ahead_bench.py [--scale 2]
"""
import argparse
import os
import re
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from scale_bench import OPTIONS, generate, mib, run, size_bytes  # noqa: E402

FRAME = re.compile(r"^frame (\d+)/(\d+): ([0-9.]+) ms", re.M)
RANK_LINE = re.compile(r"^  rank (\d+):", re.M)
PAGES = re.compile(r"decoded pages: [0-9.]+% hits \(\d+ of \d+ samples\), (\d+) decoded, \d+ "
                   r"evicted, .*?, (\d+) samples waited for a page another thread decoded; "
                   r"(\d+) pages decoded ahead of the rays$", re.M)
SIZE = r"([0-9.]+ [KMGT]?i?B|\d+ B)"
MEMORY = re.compile(r"^rank (\d+) on \S+: resident %s, peak %s; private %s, shared %s \(its share\), "
                    r"mapped files %s \(shared by the ranks on one host\)$"
                    % (SIZE, SIZE, SIZE, SIZE, SIZE), re.M)


def render(args, path, frames, degrees, ranks=0, voxwall=None):
    """One job: ([frame ms], [(pages decoded on the rays, ahead) per frame], [waited per frame],
    {rank: (private bytes, share of host-shared bytes, mapped bytes)}, the job's wall-clock seconds). ranks 0: one process
    with every core. With another `voxwall` (--compare): the frame times and the wall clock
    only."""
    cmd = [voxwall or args.voxwall, "render", path, "--size", args.size, "--frames", str(frames),
           "--orbit-deg", str(degrees), "--camera", "30,20,2.2", "--shading", "--exact",
           "--no-write", "-v"]
    env = None
    if ranks:
        cmd = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-np", str(ranks)] + cmd + [
            "--balance", "static", "--threads", "1"]
        env = dict(os.environ, OMPI_MCA_rmaps_base_oversubscribe="1")
    began = time.monotonic()
    out = run(cmd, env)
    wall = time.monotonic() - began
    times = {int(m.group(1)): float(m.group(3)) for m in FRAME.finditer(out)}
    if sorted(times) != list(range(1, frames + 1)):
        sys.exit("cannot find %d frame times in the output of %s:\n%s"
                 % (frames, " ".join(cmd), out[-4000:]))
    if voxwall:
        return [times[f] for f in range(1, frames + 1)], [], [], {}, wall
    # Each frame's block runs from its `frame N/M` line to the next.
    starts = [m.start() for m in FRAME.finditer(out)] + [len(out)]
    decoded, waited = [], []
    for k in range(frames):
        block = out[starts[k]:starts[k + 1]]
        lines = PAGES.findall(block)
        if not lines and os.path.basename(path) != "raw.vwz":
            sys.exit("no page line for frame %d of %s:\n%s" % (k + 1, " ".join(cmd), block))
        decoded.append((sum(int(d) for d, _, _ in lines), sum(int(a) for _, _, a in lines)))
        waited.append(sum(int(w) for _, w, _ in lines))
    memory = {int(m.group(1)): (size_bytes(m.group(4)), size_bytes(m.group(5)),
                                size_bytes(m.group(6)))
              for m in MEMORY.finditer(out)}
    if len(memory) != max(ranks, 1):
        sys.exit("cannot find %d ranks' memory in the output of %s:\n%s"
                 % (max(ranks, 1), " ".join(cmd), out[-4000:]))
    return [times[f] for f in range(1, frames + 1)], decoded, waited, memory, wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--voxwall", default="build/master/voxwall")
    ap.add_argument("--scale", type=float, default=2)
    ap.add_argument("--size", default="1920x1080")
    ap.add_argument("--codecs", default="raw,vq,svmm,ksvd,tvq,zfp")
    ap.add_argument("--ranks", default="2,4", help="rank counts of one thread each (besides 1)")
    ap.add_argument("--work", help="a directory that keeps the volume's files between runs: "
                    "those found there are used again (each codec's CODEC.vwz, whatever --scale "
                    "made them)")
    ap.add_argument("--compare", help="another voxwall binary (an earlier build) whose frame "
                    "ratios the tables show beside this one's, from the same files in the same run")
    args = ap.parse_args()
    codecs = args.codecs.split(",")
    if "raw" not in codecs:
        sys.exit("--codecs must include raw: every frame is compared with raw's")
    for c in codecs:
        if c not in OPTIONS:
            sys.exit("unknown codec %s (expected one of %s)" % (c, ", ".join(OPTIONS)))
    rank_counts = [1] + [int(n) for n in args.ranks.split(",") if n]
    with tempfile.TemporaryDirectory(prefix="voxwall-ahead-") as temporary:
        work = args.work or temporary
        os.makedirs(work, exist_ok=True)
        files = {c: os.path.join(work, c + ".vwz") for c in codecs}
        missing = [c for c in codecs if not os.path.exists(files[c])]
        if missing:
            print("generating the volume (MRI x%g)" % args.scale, file=sys.stderr)
            source, dims = generate(args.voxwall, args.scale, work)
            for c in missing:
                print("compressing as %s" % c, file=sys.stderr)
                run([args.voxwall, "compress", source, "--dims", ",".join(map(str, dims)),
                     "--type", "uint8", "--codec", c, "-q", "-o", files[c]] + OPTIONS[c])
            os.remove(source)
        info = run([args.voxwall, "info", files["raw"]])
        m = re.search(r"^dims\s+(\d+) x (\d+) x (\d+) ", info, re.M)
        if not m:
            sys.exit("cannot find the volume's dims in:\n" + info)
        dims = [int(m.group(i)) for i in (1, 2, 3)]
        print("%s uint8, %s, shaded, --exact, default --decode-cache (512M)\n"
              % ("x".join(map(str, dims)), args.size))
        print("One rank, every core: frame time over raw's same frame; pages decoded and samples "
              "that waited for another thread's page\n")
        before = " (before: %s)" % args.compare if args.compare else ""
        print("*first picture*: from the job's start (the volume opened, its value ranges made) "
              "to the end of its first frame, over raw's\n")
        print("| codec | first picture%s | first frame%s | 90 deg frames 2-4%s | 5 deg frames "
              "2-6%s | pages decoded on the rays / ahead (90 deg, frames 1-4) | waited (frame 1) "
              "| private | shared (its share) | mapped files |"
              % (before, before, before, before))
        print("|---|---|---|---|---|---|---|---|---|---|")
        one, old = {}, {}
        for c in codecs:
            print("rendering %s" % c, file=sys.stderr)
            one[c] = (render(args, files[c], 4, 90), render(args, files[c], 6, 5))
            if args.compare:
                old[c] = (render(args, files[c], 4, 90, voxwall=args.compare),
                          render(args, files[c], 6, 5, voxwall=args.compare))

        def first_picture(run_):
            """Seconds from the job's start to its first frame: the wall clock less frames 2-4."""
            times, wall = run_[0], run_[4]
            return wall - sum(times[1:]) / 1e3

        def ratios(runs, c):
            (t90, _, _, _, _), (t5, _, _, _, _) = runs[c]
            (r90, _, _, _, _), (r5, _, _, _, _) = runs["raw"]
            return (first_picture(runs[c][0]) / first_picture(runs["raw"][0]), t90[0] / r90[0],
                    sum(t90[1:]) / sum(r90[1:]), sum(t5[1:]) / sum(r5[1:]))

        for c in codecs:
            (_, d90, w90, mem, _), _ = one[c]
            now = ratios(one, c)
            was = ratios(old, c) if args.compare else None
            cells = ["%.2f (%.2f)" % (now[i], was[i]) if was else "%.2f" % now[i]
                     for i in range(4)]
            print("| %s | %s | %s | %s | %s | %s | %d | %s | %s | %s |"
                  % (c, cells[0], cells[1], cells[2], cells[3],
                     ", ".join("%d / %d" % d for d in d90), w90[0], mib(mem[0][0]),
                     mib(mem[0][1]), mib(mem[0][2])))
        print()
        print("Ranks of one thread each (strip cut, --balance static), 90-degree orbit: frame "
              "time over raw's on as many ranks; own memory (private plus its share of the host's shared "
              "memory) of the largest rank\n")
        head = " | ".join("%d: first, 2-4" % n for n in rank_counts)
        mem_head = " | ".join("own, %d" % n for n in rank_counts)
        print("| codec | %s | %s | %d ranks / 1 |" % (head, mem_head, rank_counts[-1]))
        print("|---|" + "---|" * (2 * len(rank_counts) + 1))
        per, perOld = {}, {}
        for c in codecs:
            print("rendering %s on ranks" % c, file=sys.stderr)
            per[c] = {n: render(args, files[c], 4, 90, ranks=n) for n in rank_counts}
            if args.compare:
                perOld[c] = {n: render(args, files[c], 4, 90, ranks=n, voxwall=args.compare)
                             for n in rank_counts}
        for c in codecs:
            cells, mems = [], []
            for n in rank_counts:
                t, _, _, mem, _ = per[c][n]
                r = per["raw"][n][0]
                cell = "%.2f, %.2f" % (t[0] / r[0], sum(t[1:]) / sum(r[1:]))
                if args.compare:
                    t, r = perOld[c][n][0], perOld["raw"][n][0]
                    cell += " (%.2f, %.2f)" % (t[0] / r[0], sum(t[1:]) / sum(r[1:]))
                cells.append(cell)
                mems.append(max(m[0] + m[1] for m in mem.values()))
            print("| %s | %s | %s | %.2f |" % (c, " | ".join(cells), " | ".join(map(mib, mems)),
                                               mems[-1] / mems[0]))


if __name__ == "__main__":
    main()
