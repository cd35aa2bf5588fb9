// FrameContext::compute_dims_columns: the dims of many keypoints at once, region by region (the
// inverted-file path of the classifier), with an AVX-512 kernel where the CPU has one. The same
// integer arithmetic as FrameContext::compute_dims (common/context_embedding.cc), so the same bytes.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numeric>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "common/context_embedding.h"
#include "common/context_embedding_inl.h"
#include "common/cpu_dispatch.h"
#include "common/error.h"
#include "common/hamming.h"

namespace lmb {

namespace {

#if defined(__x86_64__)
const bool kHasAvx512Columns =
    (__builtin_cpu_init(), __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
                               __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512vl") &&
                               __builtin_cpu_supports("avx512vpopcntdq"));

// The frame's tables compute_dims_columns reads (see FrameContext's members of the same names).
struct ColumnTables {
  const uint64_t* dom;
  int32_t dom_stride;  // n + 1
  const uint64_t* bin_magic;
  const int32_t* row8_x;
  const uint8_t* local8_y;  // 3 readable bytes past the end (read as 32-bit words)
  const uint8_t* tables8;   // likewise
  int32_t num_words;
};

#define LMB_COLUMNS_TARGET __attribute__((target("avx512f,avx512bw,avx512dq,avx512vl,avx512vpopcntdq")))

// GCC 12 warns that its own extract, convert, shift and gather intrinsics read their undefined
// pass-through operand (a false positive: the mask is all ones).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

// Dominance counts (FrameContext::dominance) of 8 (x rank, y rank) pairs: ix / kDomBlock as
// (ix * 43691) >> 21 (exact for ix < 2^16: the error ix / 3 / 2^21 stays below 1 / 48).
LMB_COLUMNS_TARGET inline __m256i dominance8(const ColumnTables& t, __m256i ix, __m256i iy) {
  const __m256i block = _mm256_srli_epi32(_mm256_mullo_epi32(ix, _mm256_set1_epi32(43691)), 21);
  const __m256i at = _mm256_add_epi32(_mm256_mullo_epi32(block, _mm256_set1_epi32(t.dom_stride)), iy);
  const __m256i shift = _mm256_sub_epi32(ix, _mm256_mullo_epi32(block, _mm256_set1_epi32(48)));
  const __m512i e = _mm512_i32gather_epi64(at, reinterpret_cast<const long long*>(t.dom), 8);
  const __m512i one = _mm512_set1_epi64(1);
  const __m512i below = _mm512_sub_epi64(_mm512_sllv_epi64(one, _mm512_cvtepu32_epi64(shift)), one);
  const __m512i count = _mm512_add_epi64(_mm512_srli_epi64(e, 48), _mm512_popcnt_epi64(_mm512_and_si512(e, below)));
  return _mm512_cvtepi64_epi32(count);
}

LMB_COLUMNS_TARGET inline __m512i dominance16(const ColumnTables& t, __m512i ix, __m512i iy) {
  const __m256i lo = dominance8(t, _mm512_castsi512_si256(ix), _mm512_castsi512_si256(iy));
  const __m256i hi = dominance8(t, _mm512_extracti64x4_epi64(ix, 1), _mm512_extracti64x4_epi64(iy, 1));
  return _mm512_inserti64x4(_mm512_castsi256_si512(lo), hi, 1);
}

// The byte at base[index] for 16 indices (32-bit reads: 3 padding bytes past the end).
LMB_COLUMNS_TARGET inline __m512i gather_bytes(const uint8_t* base, __m512i index) {
  return _mm512_and_si512(_mm512_i32gather_epi32(index, base, 1), _mm512_set1_epi32(0xFF));
}

// context_bin_fast of 8 lanes: (x * magic) >> 40, x = 255 count + total / 2 < 2^24.
LMB_COLUMNS_TARGET inline __m128i bins8(__m256i x, __m512i magic) {
  const __m512i product = _mm512_mullo_epi64(_mm512_cvtepu32_epi64(x), magic);
  return _mm512_cvtepi64_epi8(_mm512_srli_epi64(product, 40));
}

// The bins of one region's dims (words[0, num)) for 16 keypoints, lanes in order: the region's
// rank ranges ix0..iy1, the keypoints' own ranks rx, ry and words; out gets num rows of 16 bytes.
// The same integer arithmetic as compute_dims (an empty region reads zero counts and total 0,
// whose bins are 0, so no lane branches).
LMB_COLUMNS_TARGET void column_bins_avx512(const ColumnTables& t, const int32_t* ix0p, const int32_t* ix1p,
                                           const int32_t* iy0p, const int32_t* iy1p, const int32_t* rxp,
                                           const int32_t* ryp, const int32_t* wordp, const uint8_t* words, int32_t num,
                                           uint8_t* out) {
  const __m512i ix0 = _mm512_loadu_si512(ix0p), ix1 = _mm512_loadu_si512(ix1p);
  const __m512i iy0 = _mm512_loadu_si512(iy0p), iy1 = _mm512_loadu_si512(iy1p);
  const __m512i rx = _mm512_loadu_si512(rxp), ry = _mm512_loadu_si512(ryp);
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
  const __m512i own = _mm512_loadu_si512(wordp);
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
#undef LMB_COLUMNS_TARGET
#endif

}  // namespace

LMB_CLONES_AVX2 void FrameContext::compute_dims_columns(const DimPlan& plan, const int32_t* ids, int32_t count,
                                                        const uint8_t* descriptors, uint8_t* out, size_t stride) const {
  check_plan(plan, descriptors, count);
  LMB_CHECK(count >= 0 && count <= n_ && stride >= static_cast<size_t>(count),
            "compute_dims_columns: " << count << " keypoints of " << n_ << ", stride " << stride);
  if (count == 0) return;
  // The keypoints in x order (ties: by position), with their output position.
  std::vector<std::pair<int32_t, int32_t>> visit(static_cast<size_t>(count));
  for (int32_t i = 0; i < count; ++i) {
    assert(ids[i] >= 0 && ids[i] < n_);
    visit[i] = {rank_x_[ids[i]], i};
  }
  std::sort(visit.begin(), visit.end());
  const size_t padded = (static_cast<size_t>(count) + 7) / 8 * 8;
  std::vector<float> px(padded, 0.f), py(padded, 0.f), ps(padded, 1.f);
  std::vector<int32_t> key(static_cast<size_t>(count)), pos(static_cast<size_t>(count));
  std::vector<int32_t> own_rx(padded), own_ry(padded), own_word(padded);
  for (int32_t i = 0; i < count; ++i) {
    const int32_t k = ids[visit[i].second];
    key[i] = k;
    pos[i] = visit[i].second;
    own_rx[i] = rank_x_[k];
    own_ry[i] = rank_y_[k];
    own_word[i] = word_[k];
    px[i] = x_[k];
    py[i] = y_[k];
    ps[i] = scale_[k];
  }
  const int32_t U = plan.num_used_regions();
  const int32_t* dim_begin = plan.dim_begin_.data();
  const uint8_t* dim_word = plan.dim_word_.data();
  constexpr int32_t kChunk = kMaxRankBatch;
  alignas(32) int32_t ranks[4][kChunk];
  const BinTables tables = bin_tables();
#if defined(__x86_64__)
  // 16 keypoints at a time with AVX-512 gathers where the CPU has them, for frames with the
  // dominance structure and byte tables (the rest, and other CPUs, one keypoint at a time).
  static_assert(kDomBlock == 48, "dominance8 divides by 48");
  const bool vector_columns = kHasAvx512Columns && tables.dom != nullptr && tables.tables8 != nullptr;
  const ColumnTables columns{tables.dom,      n_ + 1,         tables.bin_magic, tables.row8_x,
                             tables.local8_y, tables.tables8, num_words_};
#endif
  for (int32_t u = 0; u < U; ++u) {
    const float x0 = plan.corners_[0][u], x1 = plan.corners_[1][u];
    const float y0 = plan.corners_[2][u], y1 = plan.corners_[3][u];
    const int32_t begin = dim_begin[u], end = dim_begin[u + 1];
    for (int32_t i0 = 0; i0 < count; i0 += kChunk) {
      const int32_t m = std::min(kChunk, count - i0);
      axis_x_.keypoint_ranks(px.data() + i0, ps.data() + i0, x0, m, ranks[0]);
      axis_x_.keypoint_ranks(px.data() + i0, ps.data() + i0, x1, m, ranks[1]);
      axis_y_.keypoint_ranks(py.data() + i0, ps.data() + i0, y0, m, ranks[2]);
      axis_y_.keypoint_ranks(py.data() + i0, ps.data() + i0, y1, m, ranks[3]);
      int32_t i = 0;
#if defined(__x86_64__)
      if (vector_columns) {
        alignas(64) uint8_t bins[16 * 256];
        for (; i + 16 <= m; i += 16) {
          const int32_t v = i0 + i;
          column_bins_avx512(columns, ranks[0] + i, ranks[1] + i, ranks[2] + i, ranks[3] + i, own_rx.data() + v,
                             own_ry.data() + v, own_word.data() + v, dim_word + begin, end - begin, bins);
          for (int32_t j = begin; j < end; ++j) {
            uint8_t* o = out + static_cast<size_t>(j) * stride;
            const uint8_t* b = bins + 16 * (j - begin);
            for (int32_t l = 0; l < 16; ++l) o[pos[v + l]] = b[l];
          }
        }
      }
#endif
      for (; i < m; ++i) {
        region_bins(tables, key[i0 + i], ranks[0][i], ranks[1][i], ranks[2][i], ranks[3][i], dim_word, begin, end,
                    out + pos[i0 + i], stride);
      }
    }
  }
  const int32_t* dims = plan.dims_.data();
  const int32_t context_dims = plan.layout_.num_context_dims();
  const int32_t bytes = plan.layout_.descriptor_bytes;
  for (int32_t j = plan.num_context_; j < plan.size(); ++j) {
    const int32_t bit = dims[j] - context_dims;
    uint8_t* o = out + static_cast<size_t>(j) * stride;
    for (int32_t i = 0; i < count; ++i) {
      o[i] = static_cast<uint8_t>(descriptor_bit(descriptors + static_cast<size_t>(ids[i]) * bytes, bit));
    }
  }
}

}  // namespace lmb
