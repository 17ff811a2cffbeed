// Transfer functions: ParaView colour-map presets (RGBPoints + Points) and built-in presets,
// baked into a lookup table the per-ray code reads.
#pragma once

#include <string>
#include <vector>
#include <voxwall/node/kernels/transfer_lut.hpp>

namespace voxwall::node {

struct ColorPoint {
  double x, r, g, b;  // data value, colour in [0, 1]
};
// ParaView's piecewise-function node: value, opacity in [0, 1], and the shape of the segment to
// the next node (midpoint in (0, 1), sharpness in [0, 1]; 0.5 / 0 is linear).
struct OpacityPoint {
  double x, opacity, midpoint = 0.5, sharpness = 0.0;
};

// Opacity is per voxel length: a sample one voxel long with opacity a is composited with
// opacity a; the raycaster corrects it for its step (1 - (1 - a)^stepVoxels).
class TransferFunction {
 public:
  std::string name;
  std::vector<ColorPoint> colors;       // sorted by x
  std::vector<OpacityPoint> opacities;  // sorted by x
  // ParaView presets with "ColorSpace" other than RGB are interpolated in RGB; the reader notes
  // that here so the program can warn once.
  std::vector<std::string> warnings;

  // Names of the built-in presets: "mri", "ct-bone", "ct-soft", "grey", "hot", "cool-warm".
  static std::vector<std::string> presetNames();
  // A built-in preset over the domain [0, 1] (rescale() it to the data). Throws
  // std::invalid_argument listing the names for an unknown one.
  static TransferFunction preset(const std::string& name);
  // Reads a ParaView preset file (an array of presets or one object; the first preset with
  // RGBPoints is used) or a saved transfer function with "RGBPoints" and "Points". Points are in
  // data values. Throws FormatError("<path>: ...").
  static TransferFunction fromParaViewJson(const std::string& path);
  // Parses JSON text (as fromParaViewJson); `source` names it in errors.
  static TransferFunction fromParaViewJsonText(const std::string& text, const std::string& source);

  // Domain covered by the points: [min x, max x] over both lists.
  double domainMin() const;
  double domainMax() const;
  // Linearly maps the points' domain onto [lo, hi] (ParaView's "rescale to data range").
  TransferFunction rescaled(double lo, double hi) const;

  // Colour (r, g, b) and opacity at a data value; clamps outside the points.
  void evaluate(double x, double rgba[4]) const;

  // Bakes `entries` samples over [lo, hi] with opacity corrected for a step of `stepVoxels`.
  HostLut bake(double lo, double hi, double stepVoxels, int entries = 4096) const;
};

}  // namespace voxwall::node
