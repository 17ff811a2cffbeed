// VOXWALL_HD marks functions that run on the host and on a CUDA device.
// Under nvcc it is __host__ __device__; under a plain C++ compiler it expands to nothing,
// so every kernel header also compiles (and is unit-tested) with g++.
#pragma once

#if defined(__CUDACC__)
#define VOXWALL_HD __host__ __device__
#define VOXWALL_HD_INLINE __host__ __device__ __forceinline__
#else
#define VOXWALL_HD
#define VOXWALL_HD_INLINE inline
#endif
