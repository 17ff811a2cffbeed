#include <algorithm>
#include <cmath>
#include <numbers>
#include <voxwall/node/color_space.hpp>

namespace voxwall::node {
namespace {

constexpr double kPi = std::numbers::pi;
// D65 reference white of the CIE XYZ -> L*a*b* conversion.
constexpr double kWhite[3] = {0.9505, 1.0, 1.089};

double toLinear(double c) { return c > 0.04045 ? std::pow((c + 0.055) / 1.055, 2.4) : c / 12.92; }
double fromLinear(double c) {
  return c > 0.0031308 ? 1.055 * std::pow(c, 1.0 / 2.4) - 0.055 : 12.92 * c;
}
double labF(double t) { return t > 0.008856 ? std::cbrt(t) : 7.787 * t + 16.0 / 116.0; }
double labFInverse(double f) {
  const double cube = f * f * f;
  return cube > 0.008856 ? cube : (f - 16.0 / 116.0) / 7.787;
}

std::array<double, 3> rgbToHsv(const Rgb& c) {
  const double mx = std::max({c[0], c[1], c[2]}), mn = std::min({c[0], c[1], c[2]});
  const double delta = mx - mn;
  double h = 0.0;
  const double s = mx > 0.0 ? delta / mx : 0.0;
  if (delta > 0.0) {
    if (c[0] == mx)
      h = (c[1] - c[2]) / delta;
    else if (c[1] == mx)
      h = 2.0 + (c[2] - c[0]) / delta;
    else
      h = 4.0 + (c[0] - c[1]) / delta;
    h /= 6.0;
    if (h < 0.0) h += 1.0;
  }
  return {h, s, mx};
}

Rgb hsvToRgb(const std::array<double, 3>& hsv) {
  const double h = hsv[0] - std::floor(hsv[0]), s = hsv[1], v = hsv[2];
  const double sector = h * 6.0;
  const int i = std::min(int(sector), 5);
  const double f = sector - i;
  const double p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
  switch (i) {
    case 0:
      return {v, t, p};
    case 1:
      return {q, v, p};
    case 2:
      return {p, v, t};
    case 3:
      return {p, q, v};
    case 4:
      return {t, p, v};
    default:
      return {v, p, q};
  }
}

// Moreland, "Diverging Color Maps for Scientific Visualization" (2009): Msh is polar L*a*b*.
std::array<double, 3> labToMsh(const std::array<double, 3>& lab) {
  const double m = std::sqrt(lab[0] * lab[0] + lab[1] * lab[1] + lab[2] * lab[2]);
  const double s = m > 0.001 ? std::acos(std::clamp(lab[0] / m, -1.0, 1.0)) : 0.0;
  const double h = s > 0.001 ? std::atan2(lab[2], lab[1]) : 0.0;
  return {m, s, h};
}

std::array<double, 3> mshToLab(const std::array<double, 3>& msh) {
  return {msh[0] * std::cos(msh[1]), msh[0] * std::sin(msh[1]) * std::cos(msh[2]),
          msh[0] * std::sin(msh[1]) * std::sin(msh[2])};
}

double angleDifference(double a, double b) {
  double d = std::abs(a - b);
  while (d >= 2 * kPi) d -= 2 * kPi;
  return d > kPi ? 2 * kPi - d : d;
}

// The hue an unsaturated end point takes so the map does not turn through an unrelated hue.
double adjustHue(const std::array<double, 3>& saturated, double unsaturatedM) {
  if (saturated[0] >= unsaturatedM - 0.1) return saturated[2];
  const double spin = saturated[1] *
                      std::sqrt(unsaturatedM * unsaturatedM - saturated[0] * saturated[0]) /
                      (saturated[0] * std::sin(saturated[1]));
  // Spin away from hue 0, except in purple hues.
  return saturated[2] > -0.3 * kPi ? saturated[2] + spin : saturated[2] - spin;
}

Rgb clamp01(const Rgb& c) {
  return {std::clamp(c[0], 0.0, 1.0), std::clamp(c[1], 0.0, 1.0), std::clamp(c[2], 0.0, 1.0)};
}

Rgb diverging(const Rgb& a, const Rgb& b, double t) {
  auto msh1 = labToMsh(rgbToLab(a)), msh2 = labToMsh(rgbToLab(b));
  // Two saturated, distinct end points: pass through an unsaturated white in the middle.
  if (msh1[1] > 0.05 && msh2[1] > 0.05 && angleDifference(msh1[2], msh2[2]) > 0.33 * kPi) {
    const double mid = std::max({msh1[0], msh2[0], 88.0});
    if (t < 0.5) {
      msh2 = {mid, 0.0, 0.0};
      t *= 2.0;
    } else {
      msh1 = {mid, 0.0, 0.0};
      t = 2.0 * t - 1.0;
    }
  }
  if (msh1[1] < 0.05 && msh2[1] > 0.05)
    msh1[2] = adjustHue(msh2, msh1[0]);
  else if (msh2[1] < 0.05 && msh1[1] > 0.05)
    msh2[2] = adjustHue(msh1, msh2[0]);
  std::array<double, 3> msh;
  for (int i = 0; i < 3; ++i) msh[i] = (1 - t) * msh1[i] + t * msh2[i];
  return labToRgb(mshToLab(msh));
}

}  // namespace

std::array<double, 3> rgbToLab(const Rgb& rgb) {
  const double r = toLinear(rgb[0]), g = toLinear(rgb[1]), b = toLinear(rgb[2]);
  const double x = 0.4124 * r + 0.3576 * g + 0.1805 * b;
  const double y = 0.2126 * r + 0.7152 * g + 0.0722 * b;
  const double z = 0.0193 * r + 0.1192 * g + 0.9505 * b;
  const double fx = labF(x / kWhite[0]), fy = labF(y / kWhite[1]), fz = labF(z / kWhite[2]);
  return {116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)};
}

Rgb labToRgb(const std::array<double, 3>& lab) {
  const double fy = (lab[0] + 16.0) / 116.0, fx = lab[1] / 500.0 + fy, fz = fy - lab[2] / 200.0;
  const double x = kWhite[0] * labFInverse(fx), y = kWhite[1] * labFInverse(fy),
               z = kWhite[2] * labFInverse(fz);
  const double r = 3.2406 * x - 1.5372 * y - 0.4986 * z;
  const double g = -0.9689 * x + 1.8758 * y + 0.0415 * z;
  const double b = 0.0557 * x - 0.2040 * y + 1.0570 * z;
  // Out of gamut: scaled down by the largest channel, then clipped at 0 (as VTK's vtkMath does:
  // it keeps the hue of a too-bright colour).
  Rgb c{fromLinear(r), fromLinear(g), fromLinear(b)};
  const double largest = std::max({c[0], c[1], c[2]});
  if (largest > 1.0)
    for (auto& v : c) v /= largest;
  return clamp01(c);
}

bool colorSpaceFromName(const std::string& name, ColorSpace* space) {
  if (name == "RGB")
    *space = ColorSpace::Rgb;
  else if (name == "HSV")
    *space = ColorSpace::Hsv;
  else if (name == "Wrapped HSV")
    *space = ColorSpace::WrappedHsv;
  else if (name == "Lab" || name == "CIELAB")
    *space = ColorSpace::Lab;
  else if (name == "Diverging")
    *space = ColorSpace::Diverging;
  else if (name == "Step")
    *space = ColorSpace::Step;
  else
    return false;
  return true;
}

const char* colorSpaceName(ColorSpace space) {
  switch (space) {
    case ColorSpace::Rgb:
      return "RGB";
    case ColorSpace::Hsv:
      return "HSV";
    case ColorSpace::WrappedHsv:
      return "Wrapped HSV";
    case ColorSpace::Lab:
      return "Lab";
    case ColorSpace::Diverging:
      return "Diverging";
    case ColorSpace::Step:
      return "Step";
  }
  return "RGB";
}

Rgb interpolateColor(ColorSpace space, const Rgb& a, const Rgb& b, double t) {
  t = std::clamp(t, 0.0, 1.0);
  switch (space) {
    case ColorSpace::Rgb:
      return {a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])};
    case ColorSpace::Step:  // as VTK: a segment (a, b] takes the colour of its right node
      return t > 0.0 ? b : a;
    case ColorSpace::Hsv:
    case ColorSpace::WrappedHsv: {
      auto h1 = rgbToHsv(a), h2 = rgbToHsv(b);
      if (space == ColorSpace::WrappedHsv && std::abs(h1[0] - h2[0]) > 0.5) {
        // The short way round the hue circle.
        if (h1[0] > h2[0])
          h1[0] -= 1.0;
        else
          h2[0] -= 1.0;
      }
      std::array<double, 3> hsv;
      for (int i = 0; i < 3; ++i) hsv[i] = h1[i] + t * (h2[i] - h1[i]);
      if (hsv[0] < 0.0) hsv[0] += 1.0;
      return clamp01(hsvToRgb(hsv));
    }
    case ColorSpace::Lab: {
      const auto l1 = rgbToLab(a), l2 = rgbToLab(b);
      std::array<double, 3> lab;
      for (int i = 0; i < 3; ++i) lab[i] = l1[i] + t * (l2[i] - l1[i]);
      return labToRgb(lab);
    }
    case ColorSpace::Diverging:
      return diverging(a, b, t);
  }
  return a;
}

}  // namespace voxwall::node
