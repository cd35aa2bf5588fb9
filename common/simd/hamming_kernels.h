// Hamming kernels of common/hamming.h, one table per SIMD level (common/simd/simd_level.h).
#pragma once

#include <cstdint>

#include "common/simd/simd_level.h"

namespace lmb::detail {

struct HammingKernels {
  SimdLevel level = SimdLevel::kGeneric;
  // out[i] = Hamming distance of q (num_bytes bytes) to row i of `rows` (n contiguous rows of
  // num_bytes bytes); num_bytes >= 0, n >= 0.
  void (*rows)(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes, uint16_t* out) = nullptr;
  // The smallest of those distances (8 num_bytes + 1 when n is 0).
  int32_t (*min)(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes) = nullptr;
  // out[j] = min of query j (queries: contiguous rows of num_bytes bytes) for every set bit j of
  // `lanes` (the other entries untouched). Every row of an 8-lane group with a set bit must be
  // readable (the AVX-512 kernel loads the group's eight).
  void (*min_lanes)(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n, int32_t num_bytes,
                    int32_t* out) = nullptr;
  // out[j] = min over i of max(0, distance of query j to row i - radius[i]) for every set bit j of
  // `lanes` (8 num_bytes + 1 when n is 0); the same readability as min_lanes.
  void (*low_lanes)(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius, int64_t n,
                    int32_t num_bytes, int32_t* out) = nullptr;
};

// The table of this process's level (simd_level()).
const HammingKernels& hamming_kernels();
// The table of `level`, or null when this CPU cannot run it.
const HammingKernels* hamming_kernels(SimdLevel level);

// The per-level kernels (hamming_generic.cc, hamming_avx2.cc, hamming_avx512.cc: min_lanes and
// low_lanes with VPOPCNTDQ, hamming_neon.cc).
void hamming_rows_generic(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes, uint16_t* out);
void hamming_rows_avx2(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes, uint16_t* out);
void hamming_rows_neon(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes, uint16_t* out);
int32_t hamming_min_generic(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes);
int32_t hamming_min_avx2(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes);
int32_t hamming_min_neon(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes);
void hamming_min_lanes_generic(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n,
                               int32_t num_bytes, int32_t* out);
void hamming_min_lanes_avx2(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n, int32_t num_bytes,
                            int32_t* out);
void hamming_min_lanes_avx512(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n, int32_t num_bytes,
                              int32_t* out);
void hamming_min_lanes_neon(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n, int32_t num_bytes,
                            int32_t* out);
void hamming_low_lanes_generic(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius,
                               int64_t n, int32_t num_bytes, int32_t* out);
void hamming_low_lanes_avx2(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius,
                            int64_t n, int32_t num_bytes, int32_t* out);
void hamming_low_lanes_avx512(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius,
                              int64_t n, int32_t num_bytes, int32_t* out);
void hamming_low_lanes_neon(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius,
                            int64_t n, int32_t num_bytes, int32_t* out);

}  // namespace lmb::detail
