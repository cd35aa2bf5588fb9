// Hamming distances of one query descriptor to many rows (common/hamming.h), by the kernels of
// this process's SIMD level (common/simd/hamming_kernels.h).
#include "common/hamming.h"

#include "common/simd/hamming_kernels.h"

namespace lmb {

void hamming_rows(const uint8_t* q, const uint8_t* rows, int64_t n, int num_bytes, uint16_t* out) {
  detail::hamming_kernels().rows(q, rows, n, num_bytes, out);
}

int hamming_min(const uint8_t* q, const uint8_t* rows, int64_t n, int num_bytes) {
  return detail::hamming_kernels().min(q, rows, n, num_bytes);
}

void hamming_min_lanes(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n, int num_bytes,
                       int32_t* out) {
  detail::hamming_kernels().min_lanes(queries, lanes, rows, n, num_bytes, out);
}

void hamming_ball_low_lanes(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius,
                            int64_t n, int num_bytes, int32_t* out) {
  detail::hamming_kernels().low_lanes(queries, lanes, rows, radius, n, num_bytes, out);
}

}  // namespace lmb
