// The scoring kernels for the baseline ISA, and the kernel table of every level.
#include "infer/simd/scoring_body.h"
#include "infer/simd/scoring_kernels.h"

namespace lmb::detail {

LMB_DEFINE_SCORING_KERNELS(generic)

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
