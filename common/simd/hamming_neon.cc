// hamming_rows with NEON (aarch64 only): 16 bytes a step, CNT per byte, widened before the sum.
#if defined(__aarch64__)
#include <arm_neon.h>

#include "common/simd/hamming_body.h"
#include "common/simd/hamming_kernels.h"

namespace lmb::detail {

namespace {

// Distance of two rows of 16 kVectors bytes.
template <int kVectors>
inline int32_t distance_neon(const uint8_t* a, const uint8_t* b) {
  uint8x16_t counts = vdupq_n_u8(0);  // <= 8 kVectors <= 32 a byte lane
  for (int v = 0; v < kVectors; ++v) {
    counts = vaddq_u8(counts, vcntq_u8(veorq_u8(vld1q_u8(a + 16 * v), vld1q_u8(b + 16 * v))));
  }
  return static_cast<int32_t>(vaddvq_u16(vpaddlq_u8(counts)));
}

template <int kVectors>
inline void rows_neon(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t bytes, uint16_t* out) {
  for (int64_t i = 0; i < n; ++i) out[i] = static_cast<uint16_t>(distance_neon<kVectors>(q, rows + i * bytes));
}

template <int kVectors>
inline int32_t min_neon(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t bytes) {
  int32_t best = 8 * bytes + 1;
  for (int64_t i = 0; i < n; ++i) {
    const int32_t d = distance_neon<kVectors>(q, rows + i * bytes);
    best = d < best ? d : best;
  }
  return best;
}

template <int kVectors>
inline void min_lanes_neon(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n, int32_t bytes,
                           int32_t* out) {
  for (; lanes != 0; lanes &= lanes - 1) {
    const int j = __builtin_ctz(lanes);
    out[j] = min_neon<kVectors>(queries + int64_t{j} * bytes, rows, n, bytes);
  }
}

}  // namespace

void hamming_rows_neon(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes, uint16_t* out) {
  switch (num_bytes) {
    case 32: return rows_neon<2>(q, rows, n, num_bytes, out);
    case 64: return rows_neon<4>(q, rows, n, num_bytes, out);
    default: return rows_dispatch(q, rows, n, num_bytes, out);
  }
}

int32_t hamming_min_neon(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes) {
  switch (num_bytes) {
    case 32: return min_neon<2>(q, rows, n, num_bytes);
    case 64: return min_neon<4>(q, rows, n, num_bytes);
    default: return min_dispatch(q, rows, n, num_bytes);
  }
}

void hamming_min_lanes_neon(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n, int32_t num_bytes,
                            int32_t* out) {
  switch (num_bytes) {
    case 32: return min_lanes_neon<2>(queries, lanes, rows, n, num_bytes, out);
    case 64: return min_lanes_neon<4>(queries, lanes, rows, n, num_bytes, out);
    default: return min_lanes_dispatch(queries, lanes, rows, n, num_bytes, out);
  }
}

void hamming_low_lanes_neon(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius,
                            int64_t n, int32_t num_bytes, int32_t* out) {
  low_lanes_dispatch(queries, lanes, rows, radius, n, num_bytes, out);
}

}  // namespace lmb::detail
#endif
