// The column kernel of the context embedding: one region's bins for 16 keypoints with AVX-512
// gathers and VPOPCNTQ (compiled with the AVX-512 F, BW, DQ, VL and VPOPCNTDQ flags; x86-64
// only). The same integer arithmetic as FrameContext::compute_dims, so the same bytes. Internal
// linkage except for the kernel (see common/simd/simd_level.h).
#if defined(__x86_64__)
#include <immintrin.h>

#include "common/simd/embedding_kernels.h"

namespace lmb::detail {

namespace {

static_assert(kDomBlock == 48, "dominance8 divides by 48");

// GCC 12 warns that its own extract, convert, shift and gather intrinsics read their undefined
// pass-through operand (a false positive: the mask is all ones).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

// Dominance counts (FrameContext::dominance) of 8 (x rank, y rank) pairs: ix / kDomBlock as
// (ix * 43691) >> 21 (exact for ix < 2^16: the error ix / 3 / 2^21 stays below 1 / 48).
inline __m256i dominance8(const ColumnTables& t, __m256i ix, __m256i iy) {
  const __m256i block = _mm256_srli_epi32(_mm256_mullo_epi32(ix, _mm256_set1_epi32(43691)), 21);
  const __m256i at = _mm256_add_epi32(_mm256_mullo_epi32(block, _mm256_set1_epi32(t.dom_stride)), iy);
  const __m256i shift = _mm256_sub_epi32(ix, _mm256_mullo_epi32(block, _mm256_set1_epi32(48)));
  const __m512i e = _mm512_i32gather_epi64(at, reinterpret_cast<const long long*>(t.dom), 8);
  const __m512i one = _mm512_set1_epi64(1);
  const __m512i below = _mm512_sub_epi64(_mm512_sllv_epi64(one, _mm512_cvtepu32_epi64(shift)), one);
  const __m512i count = _mm512_add_epi64(_mm512_srli_epi64(e, 48), _mm512_popcnt_epi64(_mm512_and_si512(e, below)));
  return _mm512_cvtepi64_epi32(count);
}

inline __m512i dominance16(const ColumnTables& t, __m512i ix, __m512i iy) {
  const __m256i lo = dominance8(t, _mm512_castsi512_si256(ix), _mm512_castsi512_si256(iy));
  const __m256i hi = dominance8(t, _mm512_extracti64x4_epi64(ix, 1), _mm512_extracti64x4_epi64(iy, 1));
  return _mm512_inserti64x4(_mm512_castsi256_si512(lo), hi, 1);
}

// The byte at base[index] for 16 indices (32-bit reads: 3 padding bytes past the end).
inline __m512i gather_bytes(const uint8_t* base, __m512i index) {
  return _mm512_and_si512(_mm512_i32gather_epi32(index, base, 1), _mm512_set1_epi32(0xFF));
}

// context_bin_fast of 8 lanes: (x * magic) >> 40, x = 255 count + total / 2 < 2^24.
inline __m128i bins8(__m256i x, __m512i magic) {
  const __m512i product = _mm512_mullo_epi64(_mm512_cvtepu32_epi64(x), magic);
  return _mm512_cvtepi64_epi8(_mm512_srli_epi64(product, 40));
}

// The bins of one region's dims (words[0, num)) for 16 keypoints, lanes in order: the region's
// rank ranges ix0..iy1, the keypoints' own ranks rx, ry and words; out gets num rows of 16 bytes.
// The same integer arithmetic as compute_dims (an empty region reads zero counts and total 0,
// whose bins are 0, so no lane branches).
void column_bins_body(const ColumnTables& t, const ColumnLanes& lanes, const uint8_t* words, int32_t num,
                      uint8_t* out) {
  const __m512i ix0 = _mm512_loadu_si512(lanes.ix0), ix1 = _mm512_loadu_si512(lanes.ix1);
  const __m512i iy0 = _mm512_loadu_si512(lanes.iy0), iy1 = _mm512_loadu_si512(lanes.iy1);
  const __m512i rx = _mm512_loadu_si512(lanes.rx), ry = _mm512_loadu_si512(lanes.ry);
  const __mmask16 inside = _mm512_cmple_epi32_mask(ix0, rx) & _mm512_cmplt_epi32_mask(rx, ix1) &
                           _mm512_cmple_epi32_mask(iy0, ry) & _mm512_cmplt_epi32_mask(ry, iy1);
  const __m512i one = _mm512_set1_epi32(1);
  const __m512i total = _mm512_sub_epi32(
      _mm512_add_epi32(_mm512_sub_epi32(_mm512_sub_epi32(dominance16(t, ix1, iy1), dominance16(t, ix0, iy1)),
                                        dominance16(t, ix1, iy0)),
                       dominance16(t, ix0, iy0)),
      _mm512_maskz_mov_epi32(inside, one));
  const __m512i magic_lo =
      _mm512_i32gather_epi64(_mm512_castsi512_si256(total), reinterpret_cast<const long long*>(t.bin_magic), 8);
  const __m512i magic_hi =
      _mm512_i32gather_epi64(_mm512_extracti64x4_epi64(total, 1), reinterpret_cast<const long long*>(t.bin_magic), 8);
  const __m512i half = _mm512_srli_epi32(total, 1);
  const __m512i W = _mm512_set1_epi32(t.num_words);
  const __m512i ax0 = _mm512_mullo_epi32(ix0, W), ax1 = _mm512_mullo_epi32(ix1, W);
  const __m512i ay0 = _mm512_mullo_epi32(iy0, W), ay1 = _mm512_mullo_epi32(iy1, W);
  const __m512i own = _mm512_loadu_si512(lanes.word);
  for (int32_t j = 0; j < num; ++j) {
    const __m512i w = _mm512_set1_epi32(words[j]);
    const __m512i row0 = _mm512_i32gather_epi32(_mm512_add_epi32(ax0, w), t.row8_x, 4);
    const __m512i row1 = _mm512_i32gather_epi32(_mm512_add_epi32(ax1, w), t.row8_x, 4);
    const __m512i col0 = gather_bytes(t.local8_y, _mm512_add_epi32(ay0, w));
    const __m512i col1 = gather_bytes(t.local8_y, _mm512_add_epi32(ay1, w));
    const __m512i t11 = gather_bytes(t.tables8, _mm512_add_epi32(row1, col1));
    const __m512i t01 = gather_bytes(t.tables8, _mm512_add_epi32(row0, col1));
    const __m512i t10 = gather_bytes(t.tables8, _mm512_add_epi32(row1, col0));
    const __m512i t00 = gather_bytes(t.tables8, _mm512_add_epi32(row0, col0));
    const __mmask16 anchor = inside & _mm512_cmpeq_epi32_mask(own, w);
    const __m512i count = _mm512_sub_epi32(_mm512_add_epi32(_mm512_sub_epi32(_mm512_sub_epi32(t11, t01), t10), t00),
                                           _mm512_maskz_mov_epi32(anchor, one));
    const __m512i x = _mm512_add_epi32(_mm512_mullo_epi32(count, _mm512_set1_epi32(255)), half);
    const __m128i lo = bins8(_mm512_castsi512_si256(x), magic_lo);
    const __m128i hi = bins8(_mm512_extracti64x4_epi64(x, 1), magic_hi);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + 16 * j), _mm_unpacklo_epi64(lo, hi));
  }
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

}  // namespace

void column_bins_avx512(const ColumnTables& t, const ColumnLanes& lanes, const uint8_t* words, int32_t num,
                        uint8_t* out) {
  column_bins_body(t, lanes, words, num, out);
}

}  // namespace lmb::detail
#endif
