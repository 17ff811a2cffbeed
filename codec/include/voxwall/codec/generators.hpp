// Synthetic volumes for tests, benchmarks and the default data when no real volume is installed.
#pragma once

#include <voxwall/codec/volume.hpp>

namespace voxwall::codec {

// Menger sponge of the given level: 3^level voxels per side, 255 where solid, 0 where carved
// (Faas 2016, sect. 5.1 uses levels 4-6). Throws std::invalid_argument outside 0..7.
Volume generateMenger(int level);

// Marschner & Lobb's test signal (1994) on an n^3 grid over [-1,1]^3 with f_M = 6,
// alpha = 0.25; values in [0,1] scaled to 0..255 for uint8/uint16 (0..65535) or kept for float32.
Volume generateMarschnerLobb(int n, ScalarType type = ScalarType::UInt8);

// 3D Shepp-Logan head phantom (Kak & Slaney's ellipsoids with Toft's higher-contrast
// "modified" intensities) on an n^3 grid, values 0..1 scaled like generateMarschnerLobb.
Volume generateSheppLogan(int n, ScalarType type = ScalarType::UInt8);

// Step `step` of a time-varying field of `steps` steps on an n^3 grid over [-1, 1]^3: three
// Gaussian blobs orbiting the z axis once over the series while they bob up and down and grow,
// beside a still torus (the part of a simulation that does not change), values 0..1 scaled like
// generateMarschnerLobb. Throws std::invalid_argument for a step outside 0..steps-1.
Volume generateOrbitingBlobs(int n, int step, int steps, ScalarType type = ScalarType::UInt8);

}  // namespace voxwall::codec
