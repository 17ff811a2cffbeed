#include "option_checks.hpp"

#include <cctype>
#include <cmath>
#include <sstream>

namespace voxwall::cli {

std::string rangeError(std::string_view option, double lo, double hi, std::string_view unit) {
  std::ostringstream text;
  text.precision(15);
  text << option << " must be in [" << lo << ", " << hi << "]";
  if (!unit.empty()) text << ' ' << unit;
  return text.str();
}

std::uint64_t parseBytes(const std::string& text, std::string_view option) {
  std::size_t used = 0;
  double value = 0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  std::string unit = text.substr(used);
  if (!unit.empty() && (unit.back() == 'B' || unit.back() == 'b')) unit.pop_back();
  if (!unit.empty() && unit.back() == 'i') unit.pop_back();
  const std::string units = "KMGT";
  double scale = 1;
  if (unit.size() == 1 && units.find(char(std::toupper(unit[0]))) != std::string::npos)
    scale = std::pow(1024.0, double(units.find(char(std::toupper(unit[0]))) + 1));
  else if (!unit.empty())
    used = 0;
  if (used == 0 || !(value > 0) || !std::isfinite(value * scale))
    throw std::invalid_argument(std::string(option) +
                                ": expected a size such as 512M, 2G or 1.5GiB");
  return std::uint64_t(value * scale);
}

std::uint64_t parseBytesOrOff(const std::string& text, std::string_view option) {
  if (text == "off" || text == "0") return 0;
  try {
    return parseBytes(text, option);
  } catch (const std::invalid_argument&) {
    throw std::invalid_argument(std::string(option) +
                                ": expected a size such as 512M or 2G, or off");
  }
}

}  // namespace voxwall::cli
