// The rank kernels of the context embedding with AVX2 gathers (compiled with -mavx2 -mpopcnt;
// x86-64 only). Internal linkage except for the kernels (see common/simd/simd_level.h).
#if defined(__x86_64__)
#include <immintrin.h>

#include "common/simd/embedding_kernels.h"

namespace lmb::detail {

namespace {

// The first index in [first, end) whose coordinate is not below v (std::lower_bound, written out
// so that no library template is compiled with this file's flags).
inline int32_t lower_rank(const float* sorted, int32_t first, int32_t end, float v) {
  int32_t count = end - first;
  while (count > 0) {
    const int32_t half = count / 2;
    if (sorted[first + half] < v) {
      first += half + 1;
      count -= half + 1;
    } else {
      count = half;
    }
  }
  return first;
}

// FrameContext::Axis::ranks for 8 corners at a time: the bounds, cells and the first two
// coordinates of each cell as in Axis::cell and Axis::rank (the same IEEE float operations:
// separate multiply and add, max / min with the same operand order, truncation), with gathers;
// lanes whose cell holds more than two coordinates finish with a binary search, as in rank().
// kPerKeypoint: the bounds p[i] + s[i] * corners[0] of m keypoints and one corner (p and s have m
// rounded up to a multiple of 8 readable entries); else p[0] + s[0] * corners[i] of one keypoint
// and m corners.
template <bool kPerKeypoint>
void axis_ranks(const AxisView& axis, const float* p, const float* s, const float* corners, int32_t m, int32_t* out) {
  const float* sorted = axis.sorted;
  const uint16_t* start = axis.start;
  const float lo = axis.lo, inv = axis.inv, last = axis.last;
  // Three passes over the corners (m <= kMaxRankBatch), so that the gathers of one pass do not
  // wait on each other: bounds and cells; the cells' first ranks; the first two coordinates.
  alignas(32) float bounds[kMaxRankBatch];
  alignas(32) int32_t cells[kMaxRankBatch], firsts[kMaxRankBatch], ends[kMaxRankBatch];
  const __m256 vlo = _mm256_set1_ps(lo);
  const __m256 vinv = _mm256_set1_ps(inv), vlast = _mm256_set1_ps(last);
  for (int32_t i = 0; i < m; i += 8) {
    const __m256 vp = kPerKeypoint ? _mm256_loadu_ps(p + i) : _mm256_set1_ps(p[0]);
    const __m256 vs = kPerKeypoint ? _mm256_loadu_ps(s + i) : _mm256_set1_ps(s[0]);
    const __m256 vc = kPerKeypoint ? _mm256_set1_ps(corners[0]) : _mm256_loadu_ps(corners + i);
    const __m256 offset = _mm256_mul_ps(vs, vc);
    const __m256 bound = _mm256_add_ps(vp, offset);
    __m256 t = _mm256_mul_ps(_mm256_sub_ps(bound, vlo), vinv);
    t = _mm256_max_ps(t, _mm256_setzero_ps());  // t > 0 ? t : 0
    t = _mm256_min_ps(t, vlast);                // t < last ? t : last
    _mm256_store_ps(bounds + i, bound);
    _mm256_store_si256(reinterpret_cast<__m256i*>(cells + i), _mm256_cvttps_epi32(t));
  }
  const __m256i low16 = _mm256_set1_epi32(0xFFFF);
  for (int32_t i = 0; i < m; i += 8) {
    // start[cell] | start[cell + 1] << 16: one 32-bit read at byte 2 * cell.
    const __m256i cell = _mm256_load_si256(reinterpret_cast<const __m256i*>(cells + i));
    const __m256i se = _mm256_i32gather_epi32(reinterpret_cast<const int*>(start), cell, 2);
    _mm256_store_si256(reinterpret_cast<__m256i*>(firsts + i), _mm256_and_si256(se, low16));
    _mm256_store_si256(reinterpret_cast<__m256i*>(ends + i), _mm256_srli_epi32(se, 16));
  }
  const __m256i one = _mm256_set1_epi32(1);
  for (int32_t i = 0; i < m; i += 8) {
    const __m256 bound = _mm256_load_ps(bounds + i);
    const __m256i first = _mm256_load_si256(reinterpret_cast<const __m256i*>(firsts + i));
    const __m256i end = _mm256_load_si256(reinterpret_cast<const __m256i*>(ends + i));
    const __m256 v0 = _mm256_i32gather_ps(sorted, first, 4);  // sentinels past n
    const __m256i below0 =
        _mm256_and_si256(_mm256_cmpgt_epi32(end, first), _mm256_castps_si256(_mm256_cmp_ps(v0, bound, _CMP_LT_OQ)));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + i), _mm256_sub_epi32(first, below0));
    const int crowded = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_sub_epi32(end, first), one)));
    for (int32_t l = 0; crowded != 0 && l < 8; ++l) {  // rare: a binary search, as in rank()
      if (crowded & (1 << l)) {
        out[i + l] = static_cast<int32_t>(lower_rank(sorted, firsts[i + l], ends[i + l], bounds[i + l]));
      }
    }
  }
}
}  // namespace

void corner_ranks_avx2(const AxisView& axis, float p, float s, const float* corners, int32_t m, int32_t* out) {
  axis_ranks<false>(axis, &p, &s, corners, m, out);
}

void keypoint_ranks_avx2(const AxisView& axis, const float* p, const float* s, float corner, int32_t m, int32_t* out) {
  axis_ranks<true>(axis, p, s, &corner, m, out);
}

}  // namespace lmb::detail
#endif
