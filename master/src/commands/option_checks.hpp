// Checks the commands share for their options: a number in its range, a word among its choices,
// a size in bytes. Each throws std::invalid_argument naming the option, which `voxwall` prints as
// its one line of error.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>

namespace voxwall::cli {

// "OPTION must be in [LO, HI] UNIT", the bounds as a person writes them (3, 0.5, 600000).
std::string rangeError(std::string_view option, double lo, double hi, std::string_view unit);

// `value` when lo <= value <= hi (never NaN); else rangeError's message.
template <class T>
T inRange(T value, T lo, T hi, std::string_view option, std::string_view unit = {}) {
  if (!(value >= lo && value <= hi))
    throw std::invalid_argument(rangeError(option, double(lo), double(hi), unit));
  return value;
}

// The value `word` names among `choices`; otherwise "OPTION: expected a, b or c".
template <class T>
T choose(const std::string& word, std::string_view option,
         std::initializer_list<std::pair<const char*, T>> choices) {
  std::string expected;
  std::size_t i = 0;
  for (const auto& [name, value] : choices) {
    if (word == name) return value;
    if (i > 0) expected += i + 1 == choices.size() ? " or " : ", ";
    expected += name;
    ++i;
  }
  throw std::invalid_argument(std::string(option) + ": expected " + expected);
}

// "512M", "2G", "1.5GiB", "4096" as bytes (more than 0); throws naming `option`.
std::uint64_t parseBytes(const std::string& text, std::string_view option);
// As parseBytes, or "off" (and "0"): 0.
std::uint64_t parseBytesOrOff(const std::string& text, std::string_view option);

}  // namespace voxwall::cli
