// hamming_rows with the popcnt instruction (compiled with -mavx2 -mpopcnt; x86-64 only).
#if defined(__x86_64__)
#include "common/simd/hamming_body.h"
#include "common/simd/hamming_kernels.h"

namespace lmb::detail {

void hamming_rows_avx2(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes, uint16_t* out) {
  rows_dispatch(q, rows, n, num_bytes, out);
}

int32_t hamming_min_avx2(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes) {
  return min_dispatch(q, rows, n, num_bytes);
}

void hamming_min_lanes_avx2(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n, int32_t num_bytes,
                            int32_t* out) {
  min_lanes_dispatch(queries, lanes, rows, n, num_bytes, out);
}

void hamming_low_lanes_avx2(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius,
                            int64_t n, int32_t num_bytes, int32_t* out) {
  low_lanes_dispatch(queries, lanes, rows, radius, n, num_bytes, out);
}

}  // namespace lmb::detail
#endif
