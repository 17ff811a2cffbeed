#include "dicom_slices.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <voxwall/core/errors.hpp>

#include "dicom_checks.hpp"

namespace voxwall::codec::dicom {
namespace {

// Moves slice z of `v` by (dx, dy) voxels (bilinear, the lowest value outside the slice), which
// undoes a gantry tilt's shear.
void shiftSlice(Volume& v, int z, double dx, double dy) {
  dispatchScalar(v.type, [&](auto t) {
    using T = decltype(t);
    const int w = v.dims.x, h = v.dims.y;
    T* slice = v.as<T>().data() + std::size_t(z) * std::size_t(w) * std::size_t(h);
    const std::vector<T> src(slice, slice + std::size_t(w) * std::size_t(h));
    const double outside = v.valueMin;
    auto at = [&](int x, int y) {
      return x < 0 || y < 0 || x >= w || y >= h ? outside
                                                : double(src[std::size_t(y) * w + std::size_t(x)]);
    };
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double sx = x - dx, sy = y - dy;
        const int x0 = int(std::floor(sx)), y0 = int(std::floor(sy));
        const double fx = sx - x0, fy = sy - y0;
        const double value = (at(x0, y0) * (1 - fx) + at(x0 + 1, y0) * fx) * (1 - fy) +
                             (at(x0, y0 + 1) * (1 - fx) + at(x0 + 1, y0 + 1) * fx) * fy;
        slice[std::size_t(y) * w + std::size_t(x)] =
            std::is_floating_point_v<T> ? T(value) : T(std::lround(value));
      }
  });
}

// How far apart along `normal` two positions written with `decimals` digits after the point may
// lie from where they were (each coordinate rounded by half a unit of the last digit).
double roundingAlong(int decimals, const glm::dvec3& normal) {
  const double unit = std::pow(10.0, -double(std::min(decimals, 16)));
  return unit * (std::abs(normal.x) + std::abs(normal.y) + std::abs(normal.z));
}

// The digits the series' positions were written with: the finest any of them shows.
int positionDecimals(const std::vector<SliceHeader>& slices) {
  int most = 0;
  for (const SliceHeader& s : slices) most = std::max(most, s.decimals);
  return most;
}

void warn(const DicomOptions& options, const std::string& message) {
  if (options.warn)
    options.warn(message);
  else
    std::fprintf(stderr, "voxwall: %s\n", message.c_str());
}

// The gaps between sorted slices: equal, or the series is refused naming the missing slices or
// the unequal gap. Equal: within 1% of their median (at least 0.01 mm), or within what rounding
// the positions to the digits they were written with can move a gap (two positions to 0.1 mm on
// an oblique normal: up to 0.17 mm), with a warning when that is more than 1%.
void checkGaps(const std::vector<SliceHeader>& slices, const glm::dvec3& normal,
               const std::string& path, const std::string& name, const DicomOptions& options) {
  std::vector<double> gaps;
  for (std::size_t i = 1; i < slices.size(); ++i) {
    const double gap = slices[i].along - slices[i - 1].along;
    if (gap < 1e-3)
      throw FormatError(path, slices[i - 1].file + " and " + slices[i].file + " of " + name +
                                  " lie at the same position (" + fixed(slices[i].along, 3) +
                                  " mm along the normal): several echoes, phases or times in "
                                  "one series are not read as one volume");
    gaps.push_back(gap);
  }
  if (gaps.empty()) return;
  std::vector<double> sorted = gaps;
  std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(sorted.size() / 2),
                   sorted.end());
  const double median = sorted[sorted.size() / 2];
  const double strict = std::max(0.01, 0.01 * median);
  const int decimals = positionDecimals(slices);
  const double rounding = roundingAlong(decimals, normal) * (1 + 1e-9);
  const double tolerance = std::max(strict, rounding);
  double worst = 0;
  for (std::size_t i = 0; i < gaps.size(); ++i) {
    worst = std::max(worst, std::abs(gaps[i] - median));
    if (std::abs(gaps[i] - median) <= tolerance) continue;
    const double ratio = gaps[i] / median;
    const std::string between = slices[i].file + " and " + slices[i + 1].file;
    if (std::round(ratio) >= 2 && std::abs(gaps[i] - std::round(ratio) * median) <= tolerance) {
      const int missing = int(std::round(ratio)) - 1;
      throw FormatError(path, std::to_string(missing) +
                                  (missing == 1 ? " slice is" : " slices are") + " missing from " +
                                  name + " between " + between + ": " + fixed(gaps[i], 3) +
                                  " mm apart where the others are " + fixed(median, 3) + " mm");
    }
    throw FormatError(path, name + " has unequal gaps between its slices: " + fixed(gaps[i], 3) +
                                " mm between " + between + " where the others are " +
                                fixed(median, 3) + " mm (its positions, written to " +
                                std::to_string(decimals) + " decimals, account for " +
                                fixed(rounding, 3) + " mm)");
  }
  if (worst > strict) {
    const auto [lo, hi] = std::minmax_element(gaps.begin(), gaps.end());
    warn(options, name + ": its slice positions were written to " + std::to_string(decimals) +
                      " decimals: gaps of " + fixed(*lo, 3) + " to " + fixed(*hi, 3) +
                      " mm (at most " + fixed(100 * worst / median, 2) + "% from their median " +
                      fixed(median, 3) + " mm) are read as equal");
  }
}

}  // namespace

// The spacing of sorted slices: the least-squares gap of their positions along the normal.
double fittedGap(const std::vector<SliceHeader>& slices) {
  const double n = double(slices.size()), meanIndex = (n - 1) / 2;
  double meanAlong = 0;
  for (const SliceHeader& s : slices) meanAlong += s.along / n;
  double num = 0, den = 0;
  for (std::size_t i = 0; i < slices.size(); ++i) {
    num += (double(i) - meanIndex) * (slices[i].along - meanAlong);
    den += (double(i) - meanIndex) * (double(i) - meanIndex);
  }
  return num / den;
}

// Every slice the same size and orientation, at a position of its own along the normal: sorts
// the slices along it (each slice's ipp and along set) and returns the series' axes.
SliceAxes placeSlices(std::vector<SliceHeader>& slices, const std::string& path,
                      const std::string& name, const DicomOptions& options) {
  const SliceHeader& first = slices.front();
  for (const SliceHeader& s : slices)
    if (s.columns != first.columns || s.rows != first.rows)
      throw FormatError(s.file, "is " + std::to_string(s.columns) + "x" + std::to_string(s.rows) +
                                    " but " + first.file + " of the same series is " +
                                    std::to_string(first.columns) + "x" +
                                    std::to_string(first.rows));
  SliceAxes axes;
  if (slices.size() == 1) return axes;
  for (const SliceHeader& s : slices) {
    if (s.position.size() != 3)
      throw FormatError(s.file, "has no Image Position (Patient) to place the slice by");
    if (s.orientation.size() != 6)
      throw FormatError(s.file, "has no Image Orientation (Patient) to place the slice by");
  }
  const std::vector<double> o = first.orientation;
  axes.row = {o[0], o[1], o[2]}, axes.column = {o[3], o[4], o[5]};
  if (std::abs(glm::length(axes.row) - 1) > 1e-3 || std::abs(glm::length(axes.column) - 1) > 1e-3 ||
      std::abs(glm::dot(axes.row, axes.column)) > 1e-3)
    throw FormatError(first.file,
                      "its Image Orientation (Patient) is not two perpendicular unit "
                      "vectors");
  axes.normal = glm::normalize(glm::cross(axes.row, axes.column));
  const std::string firstFile = first.file;
  for (SliceHeader& s : slices) {
    for (int i = 0; i < 6; ++i)
      if (std::abs(s.orientation[std::size_t(i)] - o[std::size_t(i)]) > 1e-3)
        throw FormatError(s.file, "is oriented differently from " + firstFile +
                                      " in the same series (Image Orientation (Patient))");
    s.ipp = {s.position[0], s.position[1], s.position[2]};
    s.along = glm::dot(s.ipp, axes.normal);
  }
  std::stable_sort(slices.begin(), slices.end(),
                   [](const SliceHeader& a, const SliceHeader& b) { return a.along < b.along; });
  checkGaps(slices, axes.normal, path, name, options);
  return axes;
}

// A gantry tilt: each slice's position moves in the slice's plane as well as along its normal.
// Refused unless `resample`, which shifts each slice back onto a box.
void undoGantryTilt(Volume& v, const std::vector<SliceHeader>& slices, const SliceAxes& axes,
                    const std::string& path, const std::string& name, bool resample) {
  std::vector<glm::dvec2> shifts;
  double worst = 0;
  for (const SliceHeader& s : slices) {
    const glm::dvec3 offset = s.ipp - slices.front().ipp;
    const glm::dvec3 inPlane = offset - glm::dot(offset, axes.normal) * axes.normal;
    shifts.push_back(
        {glm::dot(inPlane, axes.row) / v.spacing.x, glm::dot(inPlane, axes.column) / v.spacing.y});
    worst = std::max({worst, std::abs(shifts.back().x), std::abs(shifts.back().y)});
  }
  // A tenth of a voxel, and what rounding the positions to their digits moves them in-plane.
  const double rounding = std::sqrt(3.0) * std::pow(10.0, -double(positionDecimals(slices))) /
                          std::min(v.spacing.x, v.spacing.y);
  if (worst <= 0.1 + rounding) return;
  const glm::dvec3 last = slices.back().ipp - slices.front().ipp;
  const double along = glm::dot(last, axes.normal);
  const double degrees =
      std::atan2(glm::length(last - along * axes.normal), along) * 180.0 / 3.14159265358979323846;
  if (!resample)
    throw FormatError(path, name + " is sheared by a gantry tilt of " + fixed(degrees, 1) +
                                " degrees (its slices move " + fixed(worst, 1) +
                                " voxels across the series); --resample-tilt resamples it "
                                "onto a box");
  for (int z = 0; z < v.dims.z; ++z)
    shiftSlice(v, z, shifts[std::size_t(z)].x, shifts[std::size_t(z)].y);
  v.computeRange();
}

}  // namespace voxwall::codec::dicom
