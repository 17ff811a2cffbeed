#!/usr/bin/env python3
"""Writes tests/data/vtk_colormaps.json: colours of VTK's vtkColorTransferFunction (the colour
maps ParaView applies) at 20 sample points of maps in every colour space voxwall interpolates.
The transfer-function tests compare voxwall's interpolation with it (within 1/255).

Needs Debian's python3-vtk9:  /usr/bin/python3 tests/tools/vtk_colormap_oracle.py OUT.json
"""
import json
import sys

import vtk

# (name, ParaView ColorSpace, RGBPoints): nodes chosen to cross hue boundaries, pass through
# grey and saturated colours, and be unevenly spaced.
MAPS = [
    ("Cool to Warm", "Diverging", [0, 0.231373, 0.298039, 0.752941, 1, 0.705882, 0.0156863, 0.14902]),
    ("Blue to green diverging", "Diverging", [-2, 0.1, 0.2, 0.9, 0.5, 0.9, 0.9, 0.9, 3, 0.1, 0.7, 0.2]),
    ("Lab three nodes", "Lab", [0, 0, 0, 1, 0.3, 1, 1, 0, 1, 1, 0, 0]),
    ("CIELAB two nodes", "CIELAB", [10, 0.0, 0.5, 0.1, 250, 0.9, 0.2, 0.7]),
    ("HSV red to blue", "HSV", [0, 1, 0, 0, 1, 0, 0, 1]),
    ("Wrapped HSV magenta to yellow", "Wrapped HSV", [0, 1, 0, 1, 0.6, 1, 1, 0, 1, 0.2, 0.8, 0.4]),
    ("RGB", "RGB", [0, 0, 0, 0, 0.25, 0.9, 0.1, 0.1, 1, 1, 1, 1]),
    ("Step", "Step", [0, 0.1, 0.1, 0.8, 0.4, 0.8, 0.2, 0.1, 1, 0.9, 0.9, 0.2]),
]


def colour_function(space, points):
    ctf = vtk.vtkColorTransferFunction()
    if space == "Diverging":
        ctf.SetColorSpaceToDiverging()
    elif space in ("Lab", "CIELAB"):
        ctf.SetColorSpaceToLab()
    elif space == "HSV":
        ctf.SetColorSpaceToHSV()
        ctf.HSVWrapOff()
    elif space == "Wrapped HSV":
        ctf.SetColorSpaceToHSV()
        ctf.HSVWrapOn()
    elif space == "Step":
        ctf.SetColorSpaceToStep()
    else:
        ctf.SetColorSpaceToRGB()
    for i in range(0, len(points), 4):
        ctf.AddRGBPoint(*points[i:i + 4])
    return ctf


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "tests/data/vtk_colormaps.json"
    maps = []
    for name, space, points in MAPS:
        ctf = colour_function(space, points)
        lo, hi = points[0], points[-4]
        samples = []
        for i in range(20):
            # Uneven positions (not only node midpoints), both ends included.
            x = lo + (hi - lo) * ((i / 19.0) ** 1.3)
            samples.append([x] + list(ctf.GetColor(x)))
        maps.append({"Name": name, "ColorSpace": space, "RGBPoints": points, "samples": samples})
    # One map per block and one sample per line: small, and readable in a diff.
    with open(out, "w") as f:
        f.write('{"vtk_version": %s, "maps": [\n' % json.dumps(vtk.vtkVersion.GetVTKVersion()))
        for n, m in enumerate(maps):
            head = {k: m[k] for k in ("Name", "ColorSpace", "RGBPoints")}
            f.write(" " + json.dumps(head)[:-1] + ', "samples": [\n')
            f.write(",\n".join("  " + json.dumps(sample) for sample in m["samples"]))
            f.write("]}" + ("," if n + 1 < len(maps) else "") + "\n")
        f.write("]}\n")
    print(f"{out}: {len(maps)} maps x 20 samples from VTK {vtk.vtkVersion.GetVTKVersion()}")


if __name__ == "__main__":
    main()
