// Hamming distances between binary descriptors stored as flat uint8 rows.
#pragma once

#include <cstdint>
#include <cstring>

namespace lmb {

// Hamming distance of two descriptors of `num_bytes` bytes each.
inline int hamming_distance(const uint8_t* a, const uint8_t* b, int num_bytes) {
  int d = 0;
  int i = 0;
  for (; i + 8 <= num_bytes; i += 8) {
    uint64_t x, y;
    std::memcpy(&x, a + i, 8);
    std::memcpy(&y, b + i, 8);
    d += __builtin_popcountll(x ^ y);
  }
  for (; i < num_bytes; ++i) d += __builtin_popcount(static_cast<unsigned>(a[i] ^ b[i]));
  return d;
}

// out[i] = Hamming distance of q to row i of `rows` (n rows of num_bytes each, contiguous), with
// the kernel of the process's SIMD level (common/simd/simd_level.h: popcnt on x86 with AVX2, CNT
// with NEON): ~1 ns per 64-byte pair against ~10 ns through libgcc's popcount call.
void hamming_rows(const uint8_t* q, const uint8_t* rows, int64_t n, int num_bytes, uint16_t* out);

// The smallest Hamming distance of q to the n rows (as hamming_rows; 8 * num_bytes + 1 when n is 0).
int hamming_min(const uint8_t* q, const uint8_t* rows, int64_t n, int num_bytes);

// out[j] = hamming_min(queries + j * num_bytes, rows, n, num_bytes) for every set bit j of `lanes`
// (up to 32 queries; the other entries untouched), in one kernel call (the rows stay in cache).
// All eight rows of each 8-lane group with a set bit must be readable.
void hamming_min_lanes(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n, int num_bytes,
                       int32_t* out);

// The least distance from each query of the set bits j of `lanes` to a point of n balls (centre
// row i of `rows`, radius[i] bits): out[j] = min over i of max(0, d(query j, row i) - radius[i]),
// 8 * num_bytes + 1 when n is 0; by the triangle inequality no descriptor within radius[i] of
// row i is nearer the query. The same readability as hamming_min_lanes.
void hamming_ball_low_lanes(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius,
                            int64_t n, int num_bytes, int32_t* out);

// Bit `bit` of a descriptor (LSB-first within each byte, as OpenCV packs BRISK/ORB).
inline int descriptor_bit(const uint8_t* desc, int bit) { return (desc[bit >> 3] >> (bit & 7)) & 1; }

}  // namespace lmb
