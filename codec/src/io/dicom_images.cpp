#include "dicom_images.hpp"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <map>
#include <voxwall/core/errors.hpp>

#include "dicom_checks.hpp"

namespace voxwall::codec::dicom {
namespace {

const char* const kTimeNames[SliceHeader::kTimeKeys] = {
    "temporal position", "trigger time", "acquisition time", "content time", "instance number"};

// Positions closer than this along the normal are one position (the gap check refuses gaps this
// small between distinct slices).
constexpr double kSamePosition = 1e-3;

// The slices grouped by position along the normal of the first slice's orientation, in order
// along it; one group a slice when the slices cannot be placed (placeSlices refuses them later
// with the reason: no position, no orientation, or slices in other orientations, as a
// three-plane localizer has).
std::vector<std::vector<std::size_t>> byPosition(const std::vector<SliceHeader>& slices,
                                                 const std::vector<std::size_t>& members) {
  const SliceHeader& first = slices[members.front()];
  std::vector<std::vector<std::size_t>> groups;
  bool placeable = first.orientation.size() == 6;
  for (const std::size_t i : members) {
    const SliceHeader& s = slices[i];
    placeable = placeable && s.position.size() == 3 && s.orientation.size() == 6;
    for (std::size_t k = 0; placeable && k < 6; ++k)
      placeable = std::abs(s.orientation[k] - first.orientation[k]) <= 1e-3;
  }
  if (!placeable) {
    for (const std::size_t i : members) groups.push_back({i});
    return groups;
  }
  const auto& o = first.orientation;
  const glm::dvec3 normal = glm::cross(glm::dvec3(o[0], o[1], o[2]), glm::dvec3(o[3], o[4], o[5]));
  std::vector<std::pair<double, std::size_t>> along;
  for (const std::size_t i : members) {
    const auto& p = slices[i].position;
    along.push_back({glm::dot(glm::dvec3(p[0], p[1], p[2]), normal), i});
  }
  std::stable_sort(along.begin(), along.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  for (std::size_t k = 0; k < along.size(); ++k) {
    if (k == 0 || along[k].first - along[k - 1].first >= kSamePosition) groups.emplace_back();
    groups.back().push_back(along[k].second);
  }
  return groups;
}

// The first time key that every slice at a repeated position has and no two there share; -1
// when none does.
int timeKeyOf(const std::vector<SliceHeader>& slices,
              const std::vector<std::vector<std::size_t>>& positions) {
  for (int k = 0; k < SliceHeader::kTimeKeys; ++k) {
    bool tells = true;
    for (const auto& group : positions) {
      std::vector<double> values;
      for (const std::size_t i : group) values.push_back(slices[i].time[k]);
      std::sort(values.begin(), values.end());
      tells =
          tells &&
          std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); }) &&
          std::adjacent_find(values.begin(), values.end()) == values.end();
      if (!tells) break;
    }
    if (tells) return k;
  }
  return -1;
}

// One image's slices as time steps: each position's slices ordered in time, step t taking the
// t-th of each.
SeriesImage stepsOf(const std::vector<SliceHeader>& slices, const std::vector<std::size_t>& members,
                    const std::string& path, const std::string& name) {
  SeriesImage image;
  image.label = slices[members.front()].label;
  image.slices = members.size();
  auto positions = byPosition(slices, members);
  const std::size_t steps = positions.front().size();
  for (const auto& group : positions)
    if (group.size() != steps) {
      const auto& other = group;
      throw FormatError(
          path,
          name + " repeats its positions unequally: " + std::to_string(positions.front().size()) +
              " slices at the "
              "position of " +
              slices[positions.front().front()].file + ", " + std::to_string(other.size()) +
              " at that of " + slices[other.front()].file +
              " (every time step must have every position once)");
    }
  int key = 0;
  if (steps > 1) {
    key = timeKeyOf(slices, positions);
    if (key < 0) {
      const auto& group = positions.front();
      throw FormatError(path, slices[group[0]].file + " and " + slices[group[1]].file + " of " +
                                  name +
                                  " lie at the same position and nothing tells them apart in "
                                  "time or as images (temporal position, trigger time, "
                                  "acquisition or content time, instance number, image type, "
                                  "echo, b-value)");
    }
    image.orderedBy = kTimeNames[key];
  }
  image.steps.resize(steps);
  for (auto& group : positions) {
    std::stable_sort(group.begin(), group.end(), [&](std::size_t a, std::size_t b) {
      return slices[a].time[key] < slices[b].time[key];
    });
    for (std::size_t t = 0; t < steps; ++t) image.steps[t].push_back(slices[group[t]]);
  }
  return image;
}

}  // namespace

std::vector<SeriesImage> splitSeries(const std::vector<SliceHeader>& slices,
                                     const std::string& path, const std::string& name) {
  std::vector<std::size_t> all(slices.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
  bool repeats = false;
  for (const auto& group : byPosition(slices, all)) repeats = repeats || group.size() > 1;
  if (!repeats) {
    SeriesImage one;
    one.slices = slices.size();
    one.steps = {slices};
    return {one};
  }
  std::vector<std::string> keys;  // in order of their first slice
  std::vector<std::vector<std::size_t>> members;
  for (std::size_t i = 0; i < slices.size(); ++i) {
    const auto it = std::find(keys.begin(), keys.end(), slices[i].image);
    if (it == keys.end()) {
      keys.push_back(slices[i].image);
      members.push_back({i});
    } else {
      members[std::size_t(it - keys.begin())].push_back(i);
    }
  }
  std::vector<SeriesImage> images;
  for (const auto& m : members) {
    const std::string which =
        members.size() > 1 ? name + " image " + std::to_string(images.size() + 1) : name;
    images.push_back(stepsOf(slices, m, path, which));
  }
  return images;
}

std::string describeImages(const std::vector<SeriesImage>& images, const std::string& unit) {
  std::string list;
  for (std::size_t i = 0; i < images.size(); ++i) {
    const SeriesImage& image = images[i];
    list += (i ? "; " : "") + std::to_string(i + 1) + ": " +
            (image.label.empty() ? std::string("(no label)") : image.label) + " (" +
            std::to_string(image.slices) + " " + unit;
    if (image.steps.size() > 1) list += ", " + std::to_string(image.steps.size()) + " time steps";
    list += ")";
  }
  return list;
}

const SeriesImage& pickImage(const std::vector<SeriesImage>& images, const DicomOptions& options,
                             const std::string& where, const std::string& unit) {
  if (images.size() > 1 && options.image == 0) {
    std::size_t total = 0;
    for (const SeriesImage& image : images) total += image.slices;
    throw FormatError(where, "holds " + std::to_string(images.size()) + " images in its " +
                                 std::to_string(total) + " " + unit + " (" +
                                 describeImages(images, unit) + "); read one with --dicom-image N");
  }
  if (options.image < 0 || std::size_t(options.image) > images.size())
    throw FormatError(where, "holds " + std::to_string(images.size()) +
                                 (images.size() == 1 ? " image" : " images") + "; --dicom-image " +
                                 std::to_string(options.image) + " is not one of them");
  return images[std::size_t(std::max(options.image, 1) - 1)];
}

double secondsOfDay(const std::string& tm) {
  std::string digits;
  std::size_t i = 0;
  for (; i < tm.size() && tm[i] != '.'; ++i)
    if (tm[i] != ':') digits += tm[i];
  if (digits.size() < 2 || digits.size() > 6 || digits.size() % 2 ||
      !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return SliceHeader::kNone;
  double s = 0;
  const double scale[3] = {3600, 60, 1};
  for (std::size_t k = 0; k < digits.size() / 2; ++k)
    s += scale[k] * std::stoi(digits.substr(2 * k, 2));
  if (i < tm.size()) {
    const std::string fraction = tm.substr(i + 1);
    if (fraction.empty() || fraction.size() > 6 ||
        !std::all_of(fraction.begin(), fraction.end(), [](char c) { return c >= '0' && c <= '9'; }))
      return SliceHeader::kNone;
    s += std::stod("0." + fraction);
  }
  return s;
}

}  // namespace voxwall::codec::dicom
