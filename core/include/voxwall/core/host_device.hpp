// VOXWALL_HD marks functions that run on the host and on a CUDA device.
// Under nvcc it is __host__ __device__; under a plain C++ compiler it expands to nothing,
// so every kernel header also compiles (and is unit-tested) with g++.
#pragma once

#if defined(__CUDACC__)
#define VOXWALL_HD __host__ __device__
#define VOXWALL_HD_INLINE __host__ __device__ __forceinline__
#elif defined(__GNUC__)
#define VOXWALL_HD
// The per-sample helpers are small and called in the innermost loop: g++ does not always
// inline them on its own (RawView::sample stayed a call and cost ~15% of a frame).
#define VOXWALL_HD_INLINE inline __attribute__((always_inline))
#else
#define VOXWALL_HD
#define VOXWALL_HD_INLINE inline
#endif
