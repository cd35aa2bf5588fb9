// hamming_rows for the baseline ISA, and the kernel tables of every level.
#include "common/simd/hamming_body.h"
#include "common/simd/hamming_kernels.h"

namespace lmb::detail {

void hamming_rows_generic(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes, uint16_t* out) {
  rows_dispatch(q, rows, n, num_bytes, out);
}

int32_t hamming_min_generic(const uint8_t* q, const uint8_t* rows, int64_t n, int32_t num_bytes) {
  return min_dispatch(q, rows, n, num_bytes);
}

void hamming_min_lanes_generic(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n,
                               int32_t num_bytes, int32_t* out) {
  min_lanes_dispatch(queries, lanes, rows, n, num_bytes, out);
}

void hamming_low_lanes_generic(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius,
                               int64_t n, int32_t num_bytes, int32_t* out) {
  low_lanes_dispatch(queries, lanes, rows, radius, n, num_bytes, out);
}

namespace {

HammingKernels make_table(SimdLevel level) {
  HammingKernels k;
  k.level = level;
  k.rows = hamming_rows_generic;
  k.min = hamming_min_generic;
  k.min_lanes = hamming_min_lanes_generic;
  k.low_lanes = hamming_low_lanes_generic;
#if defined(__x86_64__)
  if (level == SimdLevel::kAvx2 || level == SimdLevel::kAvx512) {
    k.rows = hamming_rows_avx2;
    k.min = hamming_min_avx2;
    k.min_lanes = hamming_min_lanes_avx2;
    k.low_lanes = hamming_low_lanes_avx2;
    if (level == SimdLevel::kAvx512 && cpu_has_avx512_vpopcntdq()) {
      k.min_lanes = hamming_min_lanes_avx512;
      k.low_lanes = hamming_low_lanes_avx512;
    }
  }
#elif defined(__aarch64__)
  if (level == SimdLevel::kNeon) {
    k.rows = hamming_rows_neon;
    k.min = hamming_min_neon;
    k.min_lanes = hamming_min_lanes_neon;
    k.low_lanes = hamming_low_lanes_neon;
  }
#endif
  return k;
}

}  // namespace

const HammingKernels* hamming_kernels(SimdLevel level) {
  static const HammingKernels tables[] = {make_table(SimdLevel::kGeneric), make_table(SimdLevel::kAvx2),
                                          make_table(SimdLevel::kAvx512), make_table(SimdLevel::kNeon)};
  if (!simd_level_supported(level)) return nullptr;
  return &tables[static_cast<int32_t>(level)];
}

const HammingKernels& hamming_kernels() {
  static const HammingKernels* table = hamming_kernels(simd_level());
  return *table;
}

}  // namespace lmb::detail
