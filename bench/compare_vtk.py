#!/usr/bin/python3
"""voxwall's CPU raycaster next to VTK's vtkFixedPointVolumeRayCastMapper, in one run.

Same volume, image size, step (1/4 voxel; voxwall also by default: the march its error budget
picks, with the picture's PSNR against a converged render of the same camera), transfer function (bench/data/vtk-comparison-tf.json:
grey, opacity 0 at value 40 -> 0.8 at 255, opacity per voxel), camera (3/4 view: azimuth 30,
elevation 20, 2.6 bounding radii, 30 degree vertical field of view) and orbit (5 degrees per frame),
unshaded and shaded (Blinn-Phong with a headlight: ambient 0.1, diffuse 0.7, specular 0.2, power
10 in both; VTK's ShadeOn()). Prints a markdown table of ms/frame and ms x cores per frame, and
writes both first frames and a side-by-side picture to --out.

Needs Debian's python3-vtk9 and an X server for VTK's window: run it under `xvfb-run -a` with a
screen larger than the image (`-s "-screen 0 3000x2000x24"`): pixels of a window that does not fit
the screen are undefined.
Use Debian's /usr/bin/python3 (numpy, vtk); see docs/platform.md.
"""
import argparse
import math
import os
import re
import subprocess
import sys
import time

import numpy as np
import vtk
from vtk.util import numpy_support

HERE = os.path.dirname(os.path.abspath(__file__))
TF_FILE = os.path.join(HERE, "data", "vtk-comparison-tf.json")
# The two renderers' pictures agree to about 51 dB unshaded and 35 dB shaded (VTK quantizes its
# normals); below this they are not the same picture and the row's timing means nothing.
MIN_PSNR = 30.0


def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--voxwall", default=os.path.join(HERE, "..", "build", "master", "voxwall"))
    p.add_argument("--volume", default="/usr/share/mricron/templates/ch2better.nii.gz")
    p.add_argument("--size", default="1920x1080")
    p.add_argument("--frames", type=int, default=5)
    p.add_argument("--threads", default="1,2", help="comma-separated thread counts to measure")
    p.add_argument("--shading", default="off,on", help="comma-separated: off, on or both")
    p.add_argument("--out", default="bench-out/vtk")
    p.add_argument("--vtk-worker", nargs=3, metavar=("THREADS", "SHADING", "DIR"),
                   help=argparse.SUPPRESS)  # one VTK scene, in its own process (see run_vtk_fresh)
    return p.parse_args()


def run_voxwall(args, threads, shading, out_dir, march):
    """Frame times (ms), the last frame's Msamples/s and the march the frames used (from -v)."""
    # VTK's reader leaves the NIfTI's orientation aside and renders the voxel axes; voxwall is
    # told to do the same (--orientation LPS: x, y, z as stored), so both draw one picture.
    base = [args.voxwall, "render", args.volume, "--size", args.size, "--tf", TF_FILE,
            "--orientation", "LPS", "--camera", "30,20,2.6", "--fov", "30", "--orbit-deg", "5",
            "--threads", str(threads), "--background", "black", "-v"] + march
    if shading:
        base.append("--shading")
    # The first frame for the picture, then the timed frames without writing: VTK's timed renders
    # write nothing, and voxwall's background PNG writer would take a core from a 2-thread render.
    for cmd in (base + ["--frames", "1", "--out", out_dir],
                base + ["--frames", str(args.frames), "--no-write"]):
        res = subprocess.run(cmd, capture_output=True, text=True)
        if res.returncode != 0:
            sys.exit("voxwall failed: " + res.stdout + res.stderr)
    # Per frame: "frame 1/5: 812.3 ms, imbalance 1.00, render ms [0:810], 21.0 Msamples/s ...":
    # the render time is the slowest rank's (one rank here).
    ms, rate = [], []
    for ranks, msamples in re.findall(r"^frame \d+/\d+: .*?render ms \[([0-9: .]+)\], ([0-9.]+) Msamples/s",
                                      res.stdout + res.stderr, re.M):
        ms.append(max(float(r.split(":")[1]) for r in ranks.split()))
        rate.append(float(msamples))
    steps = re.findall(r"^\s+\d+ samples, .*step ([0-9.]+) voxels(, pre-integrated)?", res.stdout, re.M)
    if len(ms) != args.frames or len(steps) != args.frames:
        sys.exit(f"compare_vtk: parsed {len(ms)} of {args.frames} voxwall frame lines and {len(steps)} "
                 "of their steps; the output was:\n" + res.stdout + res.stderr)
    step, pre = steps[-1]
    return ms, rate[-1], f"{float(step):g}" + (" pre" if pre else "")


def run_reference(args, shading, out_dir):
    """The converged picture of the first camera: 1/8-voxel step, a ray a pixel."""
    cmd = [args.voxwall, "render", args.volume, "--size", args.size, "--tf", TF_FILE,
           "--orientation", "LPS", "--camera", "30,20,2.6", "--fov", "30", "--threads", "2",
           "--background", "black", "--exact", "--step", "0.125", "--frames", "1", "--out", out_dir]
    if shading:
        cmd.append("--shading")
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit("voxwall failed: " + res.stdout + res.stderr)
    return read_png(os.path.join(out_dir, "frame_00000.png"))


def vtk_scene(args, shading):
    reader = vtk.vtkNIFTIImageReader()
    reader.SetFileName(args.volume)
    reader.Update()
    image = reader.GetOutput()
    spacing = image.GetSpacing()
    dims = image.GetDimensions()
    bounds = image.GetBounds()
    center = [(bounds[0] + bounds[1]) / 2, (bounds[2] + bounds[3]) / 2, (bounds[4] + bounds[5]) / 2]
    # voxwall's bounding radius: half the diagonal of dims x spacing.
    radius = 0.5 * math.sqrt(sum((d * s) ** 2 for d, s in zip(dims, spacing)))

    color = vtk.vtkColorTransferFunction()
    color.AddRGBPoint(0, 0, 0, 0)
    color.AddRGBPoint(255, 1, 1, 1)
    opacity = vtk.vtkPiecewiseFunction()
    opacity.AddPoint(0, 0)
    opacity.AddPoint(40, 0)
    opacity.AddPoint(255, 0.8)
    prop = vtk.vtkVolumeProperty()
    prop.SetColor(color)
    prop.SetScalarOpacity(opacity)
    prop.SetInterpolationTypeToLinear()
    if shading:  # voxwall's Blinn-Phong terms; the renderer's default light is a headlight
        prop.ShadeOn()
        prop.SetAmbient(0.1)
        prop.SetDiffuse(0.7)
        prop.SetSpecular(0.2)
        prop.SetSpecularPower(10.0)
    else:
        prop.ShadeOff()
    prop.SetScalarOpacityUnitDistance(min(spacing))  # opacity per voxel, as voxwall's

    mapper = vtk.vtkFixedPointVolumeRayCastMapper()
    mapper.SetInputConnection(reader.GetOutputPort())
    mapper.SetAutoAdjustSampleDistances(0)
    mapper.SetLockSampleDistanceToInputSpacing(0)
    mapper.SetSampleDistance(0.25 * min(spacing))
    mapper.SetInteractiveSampleDistance(0.25 * min(spacing))
    mapper.SetImageSampleDistance(1.0)
    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)

    renderer = vtk.vtkRenderer()
    renderer.AddVolume(volume)
    renderer.SetBackground(0, 0, 0)
    window = vtk.vtkRenderWindow()
    window.SetOffScreenRendering(1)
    w, h = (int(v) for v in args.size.split("x"))
    window.SetSize(w, h)
    window.AddRenderer(renderer)
    return window, renderer, center, radius


def place_camera(renderer, center, radius, azimuth_deg):
    az, el = math.radians(azimuth_deg), math.radians(20.0)
    d = 2.6 * radius
    cam = renderer.GetActiveCamera()
    cam.SetFocalPoint(*center)
    cam.SetPosition(center[0] + d * math.cos(el) * math.cos(az), center[1] + d * math.cos(el) * math.sin(az),
                    center[2] + d * math.sin(el))
    cam.SetViewUp(0, 0, 1)
    cam.SetViewAngle(30)
    renderer.ResetCameraClippingRange()


def grab(window):
    f = vtk.vtkWindowToImageFilter()
    f.SetInput(window)
    f.ReadFrontBufferOff()
    f.SetInputBufferTypeToRGB()
    f.Update()
    img = f.GetOutput()
    w, h, _ = img.GetDimensions()
    arr = numpy_support.vtk_to_numpy(img.GetPointData().GetScalars()).reshape(h, w, 3)
    return arr[::-1].copy()  # VTK's rows start at the bottom


def run_vtk(args, threads, shading, out_dir):
    vtk.vtkMultiThreader.SetGlobalMaximumNumberOfThreads(threads)
    window, renderer, center, radius = vtk_scene(args, shading)
    times, first = [], None
    for f in range(args.frames + 1):  # frame 0 twice: the first render also uploads and sets up
        place_camera(renderer, center, radius, 30.0 + 5.0 * max(f - 1, 0))
        t0 = time.perf_counter()
        window.Render()
        dt = (time.perf_counter() - t0) * 1e3
        if f == 0:
            continue
        times.append(dt)
        if f == 1:
            first = grab(window)
    # Release the window's GL context now: with an earlier scene's window still alive, a later
    # (shaded) scene once drew into the wrong context and came out stretched, and slower.
    window.Finalize()
    os.makedirs(out_dir, exist_ok=True)
    write_png(os.path.join(out_dir, "frame_00000.png"), first)
    return times


def run_vtk_fresh(args, threads, shading, out_dir):
    """run_vtk in a new process: in one process, a shaded scene after other scenes came out
    stretched (the same picture at 20.7 dB every time) and slower."""
    cmd = [sys.executable, os.path.abspath(__file__), "--volume", args.volume, "--size", args.size,
           "--frames", str(args.frames), "--vtk-worker", str(threads), "on" if shading else "off",
           out_dir]
    res = subprocess.run(cmd, capture_output=True, text=True)
    m = re.search(r"^vtk ms: ([0-9., ]+)$", res.stdout, re.M)
    if res.returncode != 0 or not m:
        sys.exit("compare_vtk: the VTK worker failed:\n" + res.stdout + res.stderr)
    times = [float(v) for v in m.group(1).split(",")]
    if len(times) != args.frames:
        sys.exit(f"compare_vtk: the VTK worker timed {len(times)} of {args.frames} frames")
    return times


def write_png(path, rgb):
    h, w, _ = rgb.shape
    data = vtk.vtkUnsignedCharArray()
    data.SetNumberOfComponents(3)
    # VTK borrows the buffer (save=1): it must outlive Write(). A temporary here was freed before
    # the writer read it, and a shaded run once saved another picture's bytes.
    pixels = np.ascontiguousarray(rgb[::-1]).ravel()
    data.SetVoidArray(pixels, pixels.size, 1)
    img = vtk.vtkImageData()
    img.SetDimensions(w, h, 1)
    img.GetPointData().SetScalars(data)
    writer = vtk.vtkPNGWriter()
    writer.SetFileName(path)
    writer.SetInputData(img)
    writer.Write()


def read_png(path):
    r = vtk.vtkPNGReader()
    r.SetFileName(path)
    r.Update()
    img = r.GetOutput()
    w, h, _ = img.GetDimensions()
    n = img.GetPointData().GetScalars().GetNumberOfComponents()
    arr = numpy_support.vtk_to_numpy(img.GetPointData().GetScalars()).reshape(h, w, n)
    return arr[::-1, :, :3].copy()


def psnr(a, b):
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * math.log10(255.0 ** 2 / mse)


def main():
    args = parse_args()
    if args.vtk_worker:
        threads, shading, out_dir = args.vtk_worker
        times = run_vtk(args, int(threads), shading == "on", out_dir)
        print("vtk ms: " + ", ".join(f"{t:.3f}" for t in times))
        return
    if not os.path.exists(args.volume):
        sys.exit(f"{args.volume} not found (install Debian's mricron-data)")
    rows = []
    modes = [m.strip() for m in args.shading.split(",")]
    if not modes or any(m not in ("off", "on") for m in modes):
        sys.exit("compare_vtk: --shading takes off, on or off,on")
    for shading in [m == "on" for m in modes]:
        ref_img = run_reference(args, shading, os.path.join(args.out, f"reference-{'on' if shading else 'off'}"))
        for threads in [int(t) for t in args.threads.split(",")]:
            tag = f"{'shaded' if shading else 'unshaded'}-t{threads}"
            vdir = os.path.join(args.out, f"voxwall-{tag}")
            ddir = os.path.join(args.out, f"voxwall-default-{tag}")
            tdir = os.path.join(args.out, f"vtk-{tag}")
            vox_ms, vox_rate, _ = run_voxwall(args, threads, shading, vdir, ["--exact"])
            vox_img = read_png(os.path.join(vdir, "frame_00000.png"))
            def_ms, _, def_march = run_voxwall(args, threads, shading, ddir, [])
            def_img = read_png(os.path.join(ddir, "frame_00000.png"))
            # Never report a row whose pictures differ (VTK once drew a stretched view, with the
            # timing of that picture): try once more, then give up on the row.
            for attempt in range(2):
                vtk_ms = run_vtk_fresh(args, threads, shading, tdir)
                vtk_img = read_png(os.path.join(tdir, "frame_00000.png"))
                if psnr(vox_img, vtk_img) >= MIN_PSNR:
                    break
                print(f"compare_vtk: VTK's {tag} picture differs from voxwall's "
                      f"({psnr(vox_img, vtk_img):.1f} dB), attempt {attempt + 1}", file=sys.stderr)
            rows.append((shading, threads, np.mean(vox_ms), np.mean(vtk_ms), vox_rate,
                         psnr(vox_img, vtk_img), np.mean(def_ms), def_march, psnr(def_img, ref_img),
                         psnr(vox_img, ref_img)))
            both = np.concatenate([vox_img, vtk_img], axis=1)
            write_png(os.path.join(args.out, f"side-by-side-{tag}.png"), both)

    print(f"\nvolume {args.volume}, {args.size}, {args.frames} frames orbiting 5 deg/frame, "
          f"{os.cpu_count()} cores; VTK and voxwall 1/4 at a 1/4-voxel step, voxwall default at the "
          "march its 50 dB error budget picks; PSNR vs converged: the first frame against a "
          "1/8-voxel-step render of the same camera\n")
    print("| shading | threads | VTK ms/frame | voxwall 1/4 ms/frame | speed-up | voxwall 1/4 Msamples/s | "
          "PSNR voxwall 1/4 vs VTK (dB) | voxwall 1/4 vs converged (dB) | voxwall default ms/frame (march) | "
          "default speed-up | default vs converged (dB) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for shading, t, vox, vt, rate, p, dms, dmarch, dp, vp in rows:
        print(f"| {'on' if shading else 'off'} | {t} | {vt:.0f} | {vox:.0f} | {vt / vox:.2f}x | {rate:.1f} | "
              f"{p:.1f} | {vp:.1f} | {dms:.0f} ({dmarch}) | {vt / dms:.2f}x | {dp:.1f} |")
    bad = [(row[0], row[1], row[5]) for row in rows if row[5] < MIN_PSNR]
    for shading, t, p in bad:
        print(f"\ncompare_vtk: the {'shaded' if shading else 'unshaded'} {t}-thread pictures differ "
              f"({p:.1f} dB < {MIN_PSNR} dB): that row compares different pictures",
              file=sys.stderr)
    by = {(row[0], row[1]): row[2] for row in rows}
    for t in sorted({row[1] for row in rows}):
        if (False, t) in by and (True, t) in by:
            print(f"\nvoxwall shaded / unshaded frame, {t} thread(s): {by[(True, t)] / by[(False, t)]:.2f}")
    print(f"\nimages: {os.path.abspath(args.out)}/side-by-side-*.png (left voxwall, right VTK)")
    if bad:
        sys.exit(1)


if __name__ == "__main__":
    main()
