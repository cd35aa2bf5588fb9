// The scoring kernels for the baseline ISA, and the kernel table of every level.
#include "infer/simd/scoring_body.h"
#include "infer/simd/scoring_kernels.h"

#if defined(__x86_64__)
#include <emmintrin.h>
#endif

namespace lmb::detail {

LMB_DEFINE_SCORING_KERNELS_REST(generic)

#if defined(__x86_64__)
// The accumulations with SSE2, the x86-64 baseline, 8 lanes a pass (four registers of 2 doubles):
// the portable 4-double body compiled for SSE2 is ~18x slower than AVX2, because SSE2 has no
// 64-bit compare (its selects become bit tests) and its 16 accumulators spill. Each lane adds
// the stump output its fire bit selects, in list order: the same doubles as every other level.
namespace {

// out[j] = bias + the outputs of `stumps` in lane first + j, j < 8.
void accumulate8(double bias, const int32_t* stumps, int64_t count, const DenseStump* dense, const uint32_t* fire,
                 int32_t first, double* out) {
  // Register v holds lanes first + 2 v (low double) and first + 2 v + 1 (high): both 32-bit halves
  // of a double's mask test that lane's bit.
  __m128i bit[4];
  for (int32_t v = 0; v < 4; ++v) {
    const int32_t lo = static_cast<int32_t>(1u << (first + 2 * v)),
                  hi = static_cast<int32_t>(1u << (first + 2 * v + 1));
    bit[v] = _mm_set_epi32(hi, hi, lo, lo);
  }
  __m128d acc[4];
  for (int32_t v = 0; v < 4; ++v) acc[v] = _mm_set1_pd(bias);
  for (int64_t e = 0; e < count; ++e) {
    const int32_t s = stumps[e];
    const __m128i f = _mm_set1_epi32(static_cast<int32_t>(fire[s]));
    const __m128d a = _mm_set1_pd(dense[s].above), b = _mm_set1_pd(dense[s].below);
    for (int32_t v = 0; v < 4; ++v) {
      const __m128d set = _mm_castsi128_pd(_mm_cmpeq_epi32(_mm_and_si128(f, bit[v]), bit[v]));
      acc[v] = _mm_add_pd(acc[v], _mm_or_pd(_mm_and_pd(set, a), _mm_andnot_pd(set, b)));
    }
  }
  for (int32_t v = 0; v < 4; ++v) _mm_storeu_pd(out + 2 * v, acc[v]);
}

}  // namespace

void accumulate_lanes_generic(double bias, const int32_t* stumps, int64_t count, const DenseStump* dense,
                              const uint32_t* fire, double* out) {
  for (int32_t first = 0; first < kScoringBatch; first += 8) {
    accumulate8(bias, stumps, count, dense, fire, first, out + first);
  }
}

void accumulate_two_generic(double bias0, const int32_t* stumps0, int64_t count0, double bias1, const int32_t* stumps1,
                            int64_t count1, const DenseStump* dense, const uint32_t* fire, double* out0, double* out1) {
  accumulate_lanes_generic(bias0, stumps0, count0, dense, fire, out0);
  accumulate_lanes_generic(bias1, stumps1, count1, dense, fire, out1);
}

void accumulate_groups_generic(const GroupItem* items, int32_t n, const DenseStump* dense, const uint32_t* fire) {
  for (int32_t i = 0; i < n; ++i) {
    accumulate8(items[i].bias, items[i].stumps, items[i].count, dense, fire, 8 * items[i].group, items[i].out);
  }
}
#else
LMB_DEFINE_SCORING_ACCUMULATIONS(generic)
#endif

namespace {

ScoringKernels make_table(SimdLevel level) {
  ScoringKernels k;
  k.level = level;
  k.fire_masks = fire_masks_generic;
  k.accumulate_lanes = accumulate_lanes_generic;
  k.accumulate_two = accumulate_two_generic;
  k.accumulate_groups = accumulate_groups_generic;
  k.screen_class = screen_class_generic;
  k.any_lane_passes = any_lane_passes_generic;
#if defined(__x86_64__)
  if (level == SimdLevel::kAvx2 || level == SimdLevel::kAvx512) {
    k.fire_masks = fire_masks_avx2;
    k.accumulate_lanes = accumulate_lanes_avx2;
    k.accumulate_two = accumulate_two_avx2;
    k.accumulate_groups = accumulate_groups_avx2;
    k.screen_class = screen_class_avx2;
    k.any_lane_passes = any_lane_passes_avx2;
  }
  if (level == SimdLevel::kAvx512) {
    k.accumulate_lanes = accumulate_lanes_avx512;
    k.accumulate_two = accumulate_two_avx512;
    k.accumulate_groups = accumulate_groups_avx512;
    k.screen_class = screen_class_avx512;
  }
#elif defined(__aarch64__)
  if (level == SimdLevel::kNeon) {
    k.fire_masks = fire_masks_neon;
    k.accumulate_lanes = accumulate_lanes_neon;
    k.accumulate_two = accumulate_two_neon;
    k.accumulate_groups = accumulate_groups_neon;
    k.screen_class = screen_class_neon;
    k.any_lane_passes = any_lane_passes_neon;
  }
#endif
  return k;
}

}  // namespace

const ScoringKernels* scoring_kernels(SimdLevel level) {
  static const ScoringKernels tables[] = {make_table(SimdLevel::kGeneric), make_table(SimdLevel::kAvx2),
                                          make_table(SimdLevel::kAvx512), make_table(SimdLevel::kNeon)};
  if (!simd_level_supported(level)) return nullptr;
  return &tables[static_cast<int32_t>(level)];
}

const ScoringKernels& scoring_kernels() {
  static const ScoringKernels* table = scoring_kernels(simd_level());
  return *table;
}

}  // namespace lmb::detail
