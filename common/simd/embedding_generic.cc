// The context-embedding kernels for the baseline ISA (one rank at a time, as
// FrameContext::Axis::rank), and the kernel tables of every level.
#include <algorithm>

#include "common/simd/embedding_kernels.h"

namespace lmb::detail {

namespace {

// FrameContext::Axis::cell and ::rank on a view (the same float operations).
inline int32_t axis_rank(const AxisView& a, float v) {
  float t = (v - a.lo) * a.inv;
  t = t > 0.f ? t : 0.f;
  t = t < a.last ? t : a.last;
  const int32_t c = static_cast<int32_t>(t);
  const int32_t i = a.start[c], e = a.start[c + 1];
  if (e - i <= 2) {  // branch-free (the sentinels make sorted[i + 1] readable)
    return i + static_cast<int32_t>((i < e) & (a.sorted[i] < v)) +
           static_cast<int32_t>((i + 1 < e) & (a.sorted[i + 1] < v));
  }
  return static_cast<int32_t>(std::lower_bound(a.sorted + i, a.sorted + e, v) - a.sorted);
}

// region_bound (common/context_embedding_inl.h): the product and the sum each rounded to float.
inline float bound_of(float p, float s, float c) {
  const float offset = s * c;
  const float bound = p + offset;
  return bound;
}

}  // namespace

void corner_ranks_generic(const AxisView& axis, float p, float s, const float* corners, int32_t m, int32_t* out) {
  for (int32_t i = 0; i < m; ++i) out[i] = axis_rank(axis, bound_of(p, s, corners[i]));
}

void keypoint_ranks_generic(const AxisView& axis, const float* p, const float* s, float corner, int32_t m,
                            int32_t* out) {
  for (int32_t i = 0; i < m; ++i) out[i] = axis_rank(axis, bound_of(p[i], s[i], corner));
}

namespace {

EmbeddingKernels make_table(SimdLevel level) {
  EmbeddingKernels k;
  k.level = level;
  k.corner_ranks = corner_ranks_generic;
  k.keypoint_ranks = keypoint_ranks_generic;
#if defined(__x86_64__)
  if (level == SimdLevel::kAvx2 || level == SimdLevel::kAvx512) {
    k.corner_ranks = corner_ranks_avx2;
    k.keypoint_ranks = keypoint_ranks_avx2;
  }
  if (level == SimdLevel::kAvx512 && cpu_has_avx512_vpopcntdq()) k.column_bins = column_bins_avx512;
#endif
  return k;
}

}  // namespace

const EmbeddingKernels* embedding_kernels(SimdLevel level) {
  static const EmbeddingKernels tables[] = {make_table(SimdLevel::kGeneric), make_table(SimdLevel::kAvx2),
                                            make_table(SimdLevel::kAvx512), make_table(SimdLevel::kNeon)};
  if (!simd_level_supported(level)) return nullptr;
  return &tables[static_cast<int32_t>(level)];
}

const EmbeddingKernels& embedding_kernels() {
  static const EmbeddingKernels* table = embedding_kernels(simd_level());
  return *table;
}

}  // namespace lmb::detail
