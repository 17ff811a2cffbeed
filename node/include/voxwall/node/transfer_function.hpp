// Transfer functions: ParaView colour-map presets (RGBPoints + Points) and built-in presets,
// baked into a lookup table the per-ray code reads.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>
#include <voxwall/node/color_space.hpp>
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
  std::vector<ColorPoint> colors;           // sorted by x
  std::vector<OpacityPoint> opacities;      // sorted by x
  ColorSpace colorSpace = ColorSpace::Rgb;  // how colours between points are interpolated
  // Points on [0, 1] (or [-1, 1]) that ParaView stretches over the data when it applies the map:
  // the built-in presets and ParaView's bundled presets. False: points are data values.
  bool normalized = false;
  // A built-in preset on Hounsfield units (hu-bone, ...): points are data values in HU.
  bool hounsfield = false;
  // False when the file had no opacity "Points" and the default below was put in.
  bool ownOpacity = true;
  // What the reader approximated or filled in, for the program to say once.
  std::vector<std::string> warnings;

  // Names of the built-in presets: "mri", "grey", "ct-bone", "ct-soft", "hot", "cool-warm" on
  // [0, 1], and "hu-bone", "hu-soft-tissue", "hu-lung", "hu-angio", "hu-skin" on Hounsfield units.
  static std::vector<std::string> presetNames();
  // A built-in preset: over the domain [0, 1] (rescale() it to the data), or in Hounsfield units
  // for the hu-* presets. Throws std::invalid_argument listing the names for an unknown one.
  static TransferFunction preset(const std::string& name);
  // Reads a ParaView preset file: one preset object, or a list of them (ParaView's preset list and
  // "Export" form), each with "RGBPoints" and optionally "Points", "ColorSpace", "Name"; or a
  // transfer-function state saved by the Color Map Editor (the same keys, in data values).
  // `name` picks a preset by its "Name"; empty takes the only one, and a file with several is
  // refused with their names. Points spanning exactly [0, 1] or [-1, 1] are normalized (see
  // placeOnData); others are data values. Without opacity "Points", opacity is 0 below 30% of
  // the map's range and rises to 0.8 at its top (as the built-in "mri" preset), and a warning
  // says so. Throws FormatError("<path>: ...").
  static TransferFunction fromParaViewJson(const std::string& path, const std::string& name = "");
  // Parses JSON text (as fromParaViewJson); `source` names it in errors.
  static TransferFunction fromParaViewJsonText(const std::string& text, const std::string& source,
                                               const std::string& name = "");
  // The names of the colour maps in a preset file, in file order. Throws FormatError.
  static std::vector<std::string> namesInParaViewJson(const std::string& path);
  // `--tf SPEC`: a built-in preset name, FILE, or FILE:NAME (a preset of a multi-preset file).
  static TransferFunction load(const std::string& spec);
  // How load() reads SPEC: the file and the map's name in it (file empty: a built-in preset).
  struct SpecParts {
    std::string file, name;
  };
  static SpecParts splitSpec(const std::string& spec);

  // Replaces the opacity curve with `other`'s (--opacity); the warning about a missing curve
  // goes with the old one.
  void takeOpacityFrom(const TransferFunction& other);
  // The warning a map read without opacity "Points" carries (it names the default curve).
  std::string noOpacityWarning() const;

  // Puts the map on the data as ParaView applies a preset, and says in one line what was done:
  // with `range` (--tf-range LO,HI) the points are stretched over it; otherwise normalized maps
  // are stretched over the data range [dataLo, dataHi] and maps in data values stay.
  std::string placeOnData(double dataLo, double dataHi,
                          const std::optional<std::pair<double, double>>& range);

  // Domain covered by the points: [min x, max x] over both lists.
  double domainMin() const;
  double domainMax() const;
  // Linearly maps the points' domain onto [lo, hi] (ParaView's "rescale to data range").
  TransferFunction rescaled(double lo, double hi) const;

  // Colour (r, g, b) and opacity at a data value; clamps outside the points.
  void evaluate(double x, double rgba[4]) const;

  // Bakes `entries` samples over [lo, hi] with opacity corrected for a step of `stepVoxels`; or,
  // pre-integrated, with each entry's optical depth over that step and the integral tables
  // (kernels::TransferLut says what they hold).
  HostLut bake(double lo, double hi, double stepVoxels, int entries = 4096,
               bool preIntegrate = false) const;
};

}  // namespace voxwall::node
