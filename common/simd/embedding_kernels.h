// Context-embedding kernels of FrameContext (common/context_embedding.h), one table per SIMD level
// (common/simd/simd_level.h): the ranks of region bounds along one axis, and the bins of one
// region's dims for 16 keypoints at once. The frame's tables reach them as plain pointers; every
// level gives the same ranks and bins, bit for bit.
#pragma once

#include <cstdint>

#include "common/simd/simd_level.h"

namespace lmb::detail {

// At most this many corners or keypoints per rank call.
constexpr int32_t kMaxRankBatch = 64;
// Keypoints per block of the dominance structure (FrameContext's dom_).
constexpr int32_t kDomBlock = 48;

// One axis of a frame (FrameContext::Axis): the keypoints' coordinates along it, sorted, followed
// by two +inf sentinels; a uniform grid over them: cell(v) = clamp((v - lo) * inv, 0, last)
// truncated, start[c] = the first rank whose coordinate's cell is >= c. rank(v) = the number of
// coordinates < v.
struct AxisView {
  const float* sorted = nullptr;
  const uint16_t* start = nullptr;
  float lo = 0.f;
  float inv = 0.f;
  float last = 0.f;
};

// The frame's tables the column kernel reads (FrameContext's members of the same names): the
// blocked dominance structure (row stride n + 1), context_bin_magic of every total, and the word
// tables as bytes (local8_y and tables8 have 3 readable bytes past their end).
struct ColumnTables {
  const uint64_t* dom = nullptr;
  int32_t dom_stride = 0;
  const uint64_t* bin_magic = nullptr;
  const int32_t* row8_x = nullptr;
  const uint8_t* local8_y = nullptr;
  const uint8_t* tables8 = nullptr;
  int32_t num_words = 0;
};

// 16 keypoints and one region for EmbeddingKernels::column_bins: the region's rank ranges
// [ix0, ix1) x [iy0, iy1) of each keypoint, and the keypoint's own x rank, y rank and word.
struct ColumnLanes {
  const int32_t* ix0 = nullptr;
  const int32_t* ix1 = nullptr;
  const int32_t* iy0 = nullptr;
  const int32_t* iy1 = nullptr;
  const int32_t* rx = nullptr;
  const int32_t* ry = nullptr;
  const int32_t* word = nullptr;
};

struct EmbeddingKernels {
  SimdLevel level = SimdLevel::kGeneric;
  // out[i] = rank of the bound p + s * corners[i] (region_bound: product, then sum, each rounded
  // to float) for i < m <= kMaxRankBatch; corners has m rounded up to a multiple of 8 readable
  // entries, out as many writable ones.
  void (*corner_ranks)(const AxisView& axis, float p, float s, const float* corners, int32_t m, int32_t* out) = nullptr;
  // out[i] = rank of p[i] + s[i] * corner for m <= kMaxRankBatch keypoints (p, s: m rounded up to
  // a multiple of 8 readable entries; out as many writable ones).
  void (*keypoint_ranks)(const AxisView& axis, const float* p, const float* s, float corner, int32_t m,
                         int32_t* out) = nullptr;
  // The bins of one region's dims (words[0, num)) for 16 keypoints: out gets num rows of 16 bytes,
  // the bins FrameContext::compute_dims gives (anchor excluded). Null at levels without one
  // (FrameContext then computes the bins keypoint by keypoint).
  void (*column_bins)(const ColumnTables& t, const ColumnLanes& lanes, const uint8_t* words, int32_t num,
                      uint8_t* out) = nullptr;
};

// The table of this process's level (simd_level()).
const EmbeddingKernels& embedding_kernels();
// The table of `level`, or null when this CPU cannot run it.
const EmbeddingKernels* embedding_kernels(SimdLevel level);

// The kernels of each file (embedding_generic.cc, embedding_avx2.cc, embedding_avx512.cc); a
// level's table mixes them (embedding_generic.cc).
void corner_ranks_generic(const AxisView& axis, float p, float s, const float* corners, int32_t m, int32_t* out);
void keypoint_ranks_generic(const AxisView& axis, const float* p, const float* s, float corner, int32_t m,
                            int32_t* out);
// Gathers of 8 lanes (AVX2).
void corner_ranks_avx2(const AxisView& axis, float p, float s, const float* corners, int32_t m, int32_t* out);
void keypoint_ranks_avx2(const AxisView& axis, const float* p, const float* s, float corner, int32_t m, int32_t* out);
// Gathers and VPOPCNTQ of 16 lanes (AVX-512 F, BW, DQ, VL and VPOPCNTDQ).
void column_bins_avx512(const ColumnTables& t, const ColumnLanes& lanes, const uint8_t* words, int32_t num,
                        uint8_t* out);

}  // namespace lmb::detail
