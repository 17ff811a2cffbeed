// A small test volume whose every voxel differs from its neighbours, with sides that are no block
// multiple: what the readers and sources are checked with.
#pragma once

#include <type_traits>
#include <voxwall/codec/volume.hpp>

namespace voxwall::test {

inline codec::Volume patterned(codec::ScalarType type, glm::ivec3 dims = {13, 7, 5}) {
  codec::Volume v = codec::Volume::allocate(dims, type, {0.5, 0.75, 1.25});
  codec::dispatchScalar(type, [&](auto t) {
    using T = decltype(t);
    auto out = v.as<T>();
    for (std::size_t i = 0; i < out.size(); ++i) {
      if constexpr (std::is_same_v<T, float>)
        out[i] = float(i) * 0.37f - 11.0f;
      else if constexpr (std::is_same_v<T, std::int16_t>)
        out[i] = T(int(i * 97 % 60000) - 30000);
      else
        out[i] = T(i * 131 + 7);
    }
  });
  v.computeRange();
  return v;
}

}  // namespace voxwall::test
