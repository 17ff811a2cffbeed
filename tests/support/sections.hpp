// Editing a CompressedVolume's sections, for the codecs' corrupt-file tests.
#pragma once

#include <cstring>
#include <stdexcept>
#include <vector>
#include <voxwall/codec/container.hpp>

namespace voxwall::test {

// The bytes of section `id`; throws std::logic_error when there is none.
inline std::vector<std::byte>& section(codec::CompressedVolume& c, std::uint32_t id) {
  for (auto& [sid, bytes] : c.sections)
    if (sid == id) return bytes;
  throw std::logic_error("no section " + std::to_string(id));
}

// Overwrites sizeof(T) bytes at `at` with `value`.
template <class T>
void poke(std::vector<std::byte>& bytes, std::size_t at, T value) {
  std::memcpy(bytes.data() + at, &value, sizeof value);
}

}  // namespace voxwall::test
