// Codebook training for the tvq codec's vector quantizers: LBG (Linde, Buzo and Gray, 1980) from
// a splitting initialisation, and the nearest-codevector search it and the encoder share.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace voxwall::codec::tvq {

// The nearest codevector of each of the `count` vectors (count x dims, row-major) in `codebook`
// (n x dims); ties keep the lower index. `error2` (if set) receives the summed squared error.
// Deterministic for any thread count.
std::vector<std::uint32_t> nearestCodevectors(std::span<const float> vectors, int dims,
                                              std::span<const float> codebook, int threads,
                                              double* error2 = nullptr);

// A codebook of at most `size` codevectors for `vectors` (count x dims): the vectors themselves
// when there are no more than `size`, else LBG: start from the centroid, split every codevector
// (the ones with the largest distortion first when the size is not a power of two) along its
// cell's per-dimension spread, run Lloyd iterations (3 per split, `iterations` after the last),
// re-seed an empty cell at the worst-represented vector. Deterministic for a seed.
std::vector<float> trainLbg(std::span<const float> vectors, int dims, std::size_t size,
                            int iterations, std::uint64_t seed, int threads);

}  // namespace voxwall::codec::tvq
