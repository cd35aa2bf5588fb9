// hamming_min_lanes and hamming_low_lanes with AVX-512 VPOPCNTDQ (compiled with the avx512 flags and
// -mavx512vpopcntdq; x86-64 only, chosen when the CPU has VPOPCNTDQ): eight lanes at a time, the
// k-th 64-bit word of their descriptors gathered into one register, so that one row costs a
// broadcast, an XOR, a popcount and an add per word for eight lanes.
#if defined(__x86_64__)
#include <immintrin.h>

#include "common/simd/hamming_body.h"
#include "common/simd/hamming_kernels.h"

namespace lmb::detail {
namespace {

// kRadius: min over rows of max(0, distance - radius[i]) (low_lanes); else the least distance.
template <int kWords, bool kRadius>
void min_lanes_avx512(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius, int64_t n,
                      int32_t bytes, int32_t* out) {
  const __m512i offsets = _mm512_setr_epi64(0, bytes, 2 * int64_t{bytes}, 3 * int64_t{bytes}, 4 * int64_t{bytes},
                                            5 * int64_t{bytes}, 6 * int64_t{bytes}, 7 * int64_t{bytes});
  for (int32_t g = 0; g < 4; ++g) {
    const uint32_t selected = (lanes >> (8 * g)) & 0xFFu;
    if (selected == 0) continue;
    const uint8_t* group = queries + int64_t{8 * g} * bytes;
    if (__builtin_popcount(selected) <= 2) {  // a lane or two: one lane at a time is cheaper
      for (uint32_t s = selected; s != 0; s &= s - 1) {
        const int j = __builtin_ctz(s);
        if constexpr (kRadius) {
          low_lanes_body<kWords>(group, 1u << j, rows, radius, n, bytes, out + 8 * g);
        } else {
          out[8 * g + j] = min_body<kWords>(group + int64_t{j} * bytes, rows, n, bytes);
        }
      }
      continue;
    }
    __m512i q[kWords];
    // (The masked forms: GCC 12 warns on the unmasked ones' undefined pass-through register.)
    for (int w = 0; w < kWords; ++w)
      q[w] = _mm512_mask_i64gather_epi64(_mm512_setzero_si512(), 0xFF, offsets, group + 8 * w, 1);
    __m512i best = _mm512_set1_epi64(8 * int64_t{bytes} + 1);
    for (int64_t i = 0; i < n; ++i) {
      const uint8_t* r = rows + i * bytes;
      __m512i d = _mm512_setzero_si512();
      for (int w = 0; w < kWords; ++w) {
        uint64_t x;
        std::memcpy(&x, r + 8 * w, 8);
        d = _mm512_add_epi64(d,
                             _mm512_popcnt_epi64(_mm512_xor_si512(q[w], _mm512_set1_epi64(static_cast<int64_t>(x)))));
      }
      if constexpr (kRadius) {  // max(0, d - radius[i]) (masked forms: see the gathers above)
        const __m512i zero = _mm512_setzero_si512();
        d = _mm512_mask_max_epi64(zero, 0xFF, _mm512_mask_sub_epi64(zero, 0xFF, d, _mm512_set1_epi64(radius[i])), zero);
      }
      best = _mm512_mask_min_epu64(best, 0xFF, best, d);
    }
    alignas(64) int64_t b[8];
    _mm512_store_si512(b, best);
    for (uint32_t s = selected; s != 0; s &= s - 1) {
      const int j = __builtin_ctz(s);
      out[8 * g + j] = static_cast<int32_t>(b[j]);
    }
  }
}

}  // namespace

void hamming_min_lanes_avx512(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, int64_t n, int32_t num_bytes,
                              int32_t* out) {
  switch (num_bytes) {
    case 32: return min_lanes_avx512<4, false>(queries, lanes, rows, nullptr, n, num_bytes, out);
    case 64: return min_lanes_avx512<8, false>(queries, lanes, rows, nullptr, n, num_bytes, out);
    default: return min_lanes_dispatch(queries, lanes, rows, n, num_bytes, out);
  }
}

void hamming_low_lanes_avx512(const uint8_t* queries, uint32_t lanes, const uint8_t* rows, const int32_t* radius,
                              int64_t n, int32_t num_bytes, int32_t* out) {
  switch (num_bytes) {
    case 32: return min_lanes_avx512<4, true>(queries, lanes, rows, radius, n, num_bytes, out);
    case 64: return min_lanes_avx512<8, true>(queries, lanes, rows, radius, n, num_bytes, out);
    default: return low_lanes_dispatch(queries, lanes, rows, radius, n, num_bytes, out);
  }
}

}  // namespace lmb::detail
#endif
