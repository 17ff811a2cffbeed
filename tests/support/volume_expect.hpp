// Expecting two volumes to hold the same voxels.
#pragma once

#include <gtest/gtest.h>

#include <voxwall/codec/volume.hpp>

namespace voxwall::test {

// The same size, type, voxels and value range.
inline void expectSameVoxels(const codec::Volume& a, const codec::Volume& b) {
  ASSERT_EQ(a.dims, b.dims);
  ASSERT_EQ(a.type, b.type);
  EXPECT_EQ(a.data, b.data);
  EXPECT_EQ(a.valueMin, b.valueMin);
  EXPECT_EQ(a.valueMax, b.valueMax);
}

}  // namespace voxwall::test
