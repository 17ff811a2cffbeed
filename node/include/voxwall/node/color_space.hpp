// Colour interpolation as VTK's vtkColorTransferFunction (and so ParaView) does it, for the
// colour spaces ParaView's presets name: RGB, HSV (with or without the hue wrapped around),
// CIELAB, Moreland's diverging interpolation through Msh, and Step.
#pragma once

#include <array>
#include <string>

namespace voxwall::node {

enum class ColorSpace { Rgb, Hsv, WrappedHsv, Lab, Diverging, Step };

using Rgb = std::array<double, 3>;  // linear in the file's sense: [0, 1] per channel

// ParaView's "ColorSpace" names ("RGB", "HSV", "Wrapped HSV", "Lab", "CIELAB", "Diverging",
// "Step"); false for an unknown name.
bool colorSpaceFromName(const std::string& name, ColorSpace* space);
const char* colorSpaceName(ColorSpace space);

// The colour at t in [0, 1] between a (t = 0) and b (t = 1).
Rgb interpolateColor(ColorSpace space, const Rgb& a, const Rgb& b, double t);

// Conversions (sRGB with D65 white, as VTK's vtkMath), exposed for tests.
std::array<double, 3> rgbToLab(const Rgb& rgb);
Rgb labToRgb(const std::array<double, 3>& lab);

}  // namespace voxwall::node
