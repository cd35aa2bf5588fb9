// The portable body of hamming_rows, included by hamming_generic.cc and hamming_avx2.cc, which
// compile it with their own flags (POPCNT in the AVX2 file). Internal linkage only (see
// common/simd/simd_level.h): no inline or template code shared with other files.
#pragma once

#include <cstdint>
#include <cstring>

#include "common/simd/popcount.h"

namespace lmb::detail {
namespace {

inline int32_t distance_bytes(const uint8_t* a, const uint8_t* b, int32_t num_bytes) {
  int32_t d = 0;
  int32_t i = 0;
  for (; i + 8 <= num_bytes; i += 8) {
    uint64_t x, y;
    std::memcpy(&x, a + i, 8);
    std::memcpy(&y, b + i, 8);
    d += popcount64(x ^ y);
  }
  for (; i < num_bytes; ++i) d += popcount64(static_cast<uint64_t>(a[i] ^ b[i]));
  return d;
}

// The distance of one row to a query held as kWords 64-bit words.
template <int kWords>
inline int32_t words_distance(const uint64_t* qw, const uint8_t* r) {
  int32_t d = 0;
  for (int w = 0; w < kWords; ++w) {
    uint64_t x;
    std::memcpy(&x, r + 8 * w, 8);
    d += popcount64(x ^ qw[w]);
  }
  return d;
}

// kWords > 0: rows of exactly 8 kWords bytes, the query held in registers.
template <int kWords>
inline void rows_body(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t bytes, uint16_t* out) {
  if constexpr (kWords > 0) {
    uint64_t qw[kWords];
    std::memcpy(qw, q, sizeof(qw));
    for (int64_t i = 0; i < n; ++i) out[i] = static_cast<uint16_t>(words_distance<kWords>(qw, rows + i * bytes));
  } else {
    for (int64_t i = 0; i < n; ++i) out[i] = static_cast<uint16_t>(distance_bytes(q, rows + i * bytes, bytes));
  }
}

template <int kWords>
inline int32_t min_body(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t bytes) {
  int32_t best = 8 * bytes + 1;
  if constexpr (kWords > 0) {
    uint64_t qw[kWords];
    std::memcpy(qw, q, sizeof(qw));
    for (int64_t i = 0; i < n; ++i) {
      const int32_t d = words_distance<kWords>(qw, rows + i * bytes);
      best = d < best ? d : best;
    }
  } else {
    for (int64_t i = 0; i < n; ++i) {
      const int32_t d = distance_bytes(q, rows + i * bytes, bytes);
      best = d < best ? d : best;
    }
  }
  return best;
}

inline void rows_dispatch(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t bytes, uint16_t* out) {
  switch (bytes) {
    case 32: return rows_body<4>(q, rows, n, bytes, out);
    case 64: return rows_body<8>(q, rows, n, bytes, out);
    default: return rows_body<0>(q, rows, n, bytes, out);
  }
}

inline int32_t min_dispatch(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t bytes) {
  switch (bytes) {
    case 32: return min_body<4>(q, rows, n, bytes);
    case 64: return min_body<8>(q, rows, n, bytes);
    default: return min_body<0>(q, rows, n, bytes);
  }
}

// min_body of the queries of the set bits of `lanes`, the query loop inside the kernel (no call
// per query).
template <int kWords>
inline void min_lanes_body(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n, int32_t bytes,
                           int32_t* out) {
  for (; lanes != 0; lanes &= lanes - 1) {
    const int j = __builtin_ctz(lanes);
    out[j] = min_body<kWords>(queries + int64_t{j} * bytes, rows, n, bytes);
  }
}

inline void min_lanes_dispatch(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n, int32_t bytes,
                               int32_t* out) {
  switch (bytes) {
    case 32: return min_lanes_body<4>(queries, lanes, rows, n, bytes, out);
    case 64: return min_lanes_body<8>(queries, lanes, rows, n, bytes, out);
    default: return min_lanes_body<0>(queries, lanes, rows, n, bytes, out);
  }
}

// The least distance from each query of the set bits of `lanes` to a point of the balls (centre
// row i, radius[i]): min over i of max(0, distance - radius[i]); 8 bytes + 1 when n is 0.
template <int kWords>
inline void low_lanes_body(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius,
                           int64_t n, int32_t bytes, int32_t* out) {
  for (; lanes != 0; lanes &= lanes - 1) {
    const int j = __builtin_ctz(lanes);
    const uint8_t* q = queries + int64_t{j} * bytes;
    uint64_t qw[kWords > 0 ? kWords : 1];
    if constexpr (kWords > 0) std::memcpy(qw, q, sizeof(qw));
    int32_t best = 8 * bytes + 1;
    for (int64_t i = 0; i < n; ++i) {
      int32_t d;
      if constexpr (kWords > 0) {
        d = words_distance<kWords>(qw, rows + i * bytes) - radius[i];
      } else {
        d = distance_bytes(q, rows + i * bytes, bytes) - radius[i];
      }
      d = d < 0 ? 0 : d;
      best = d < best ? d : best;
    }
    out[j] = best;
  }
}

inline void low_lanes_dispatch(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius,
                               int64_t n, int32_t bytes, int32_t* out) {
  switch (bytes) {
    case 32: return low_lanes_body<4>(queries, lanes, rows, radius, n, bytes, out);
    case 64: return low_lanes_body<8>(queries, lanes, rows, radius, n, bytes, out);
    default: return low_lanes_body<0>(queries, lanes, rows, radius, n, bytes, out);
  }
}

}  // namespace
}  // namespace lmb::detail
