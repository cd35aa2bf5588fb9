// The portable bodies of the scoring kernels (infer/simd/scoring_kernels.h), in GCC vector
// extensions: included by scoring_generic.cc (baseline ISA: SSE2 on x86-64) and scoring_avx2.cc
// (-mavx2), each compiling them with its own flags. Internal linkage only, no calls into inline
// or template code of other headers (see common/simd/simd_level.h).
#pragma once

#include <cstdint>
#include <cstring>

#include "infer/simd/scoring_kernels.h"

namespace lmb::detail {
namespace {

// 4 lanes (one AVX2 register, two SSE2 or NEON ones).
using Batch = double __attribute__((vector_size(32), aligned(8)));
using LaneMask = int64_t __attribute__((vector_size(32), aligned(8)));
constexpr int32_t kLanes = 4;
constexpr int32_t kVectors = kScoringBatch / kLanes;
static_assert(kScoringBatch == 32, "a batch's fire bits of one stump are a uint32");

inline void fire_masks_body(const DenseStump* stumps, size_t num_stumps, const uint8_t* values, size_t stride,
                            uint32_t* fire) {
  using Bytes = uint8_t __attribute__((vector_size(32), aligned(1)));
  using Words = uint64_t __attribute__((vector_size(32), aligned(8)));
  for (size_t s = 0; s < num_stumps; ++s) {
    Bytes v;
    std::memcpy(&v, values + static_cast<size_t>(stumps[s].used) * stride, sizeof(v));
    const Bytes theta = Bytes{} + stumps[s].theta;
    const Words gt = reinterpret_cast<Words>(v > theta);  // 0xFF or 0x00 a lane
    // Byte i of each word keeps only bit i; the product sums them into the top byte (no carries).
    const Words bits = (gt & 0x8040201008040201ull) * 0x0101010101010101ull;
    fire[s] = static_cast<uint32_t>(bits[0] >> 56) | static_cast<uint32_t>(bits[1] >> 56) << 8 |
              static_cast<uint32_t>(bits[2] >> 56) << 16 | static_cast<uint32_t>(bits[3] >> 56) << 24;
  }
}

// out[j] = bias + the outputs of `stumps` in lane j, for lanes [first, first + 4 kGroups): lane by
// lane the same additions in the same order as BoostModel::scores; each output is selected (not
// computed) from the stump's two doubles by the lane's fire bit.
template <int32_t kGroups>
inline void accumulate_body(double bias, const int32_t* stumps, int64_t count, const DenseStump* dense,
                            const uint32_t* fire, int32_t first, double* out) {
  // Shifting the fire bits left by shift[v] puts bit first + kLanes * v + i at the sign of lane i.
  LaneMask shift[kGroups];
  for (int32_t v = 0; v < kGroups; ++v) {
    const int64_t top = 63 - (first + kLanes * v);
    shift[v] = LaneMask{top, top - 1, top - 2, top - 3};
  }
  Batch acc[kGroups];
  for (int32_t v = 0; v < kGroups; ++v) acc[v] = Batch{bias, bias, bias, bias};
  for (int64_t e = 0; e < count; ++e) {
    const int32_t s = stumps[e];
    const LaneMask f = LaneMask{} + static_cast<int64_t>(fire[s]);
    const double above = dense[s].above, below = dense[s].below;
    const Batch a = {above, above, above, above}, b = {below, below, below, below};
    for (int32_t v = 0; v < kGroups; ++v) acc[v] += (f << shift[v]) < 0 ? a : b;
  }
  for (int32_t v = 0; v < kGroups; ++v) std::memcpy(out + kLanes * v, &acc[v], sizeof(Batch));
}

inline void accumulate_lanes_body(double bias, const int32_t* stumps, int64_t count, const DenseStump* dense,
                                  const uint32_t* fire, double* out) {
  accumulate_body<kVectors>(bias, stumps, count, dense, fire, 0, out);
}

inline void accumulate_groups_body(const GroupItem* items, int32_t n, const DenseStump* dense, const uint32_t* fire) {
  for (int32_t i = 0; i < n; ++i) {
    accumulate_body<2>(items[i].bias, items[i].stumps, items[i].count, dense, fire, 8 * items[i].group, items[i].out);
  }
}

// Screening sums of stumps[0, count) added into sums (modulo 2^16) with 16-lane vectors: a lane
// adds q where its fire bit is set (its bit of the broadcast mask ANDed with the lane's own bit).
inline void add_screen_sums(const uint16_t* stumps, int64_t count, const int16_t* q, const uint32_t* fire,
                            uint16_t* sums) {
  using Half = uint16_t __attribute__((vector_size(32), aligned(2)));
  Half bit;
  for (int32_t i = 0; i < 16; ++i) bit[i] = static_cast<uint16_t>(1u << i);
  Half lo, hi;
  std::memcpy(&lo, sums, sizeof(Half));
  std::memcpy(&hi, sums + 16, sizeof(Half));
  for (int64_t e = 0; e < count; ++e) {
    const uint32_t s = stumps[e];
    const uint32_t f = fire[s];
    const Half v = Half{} + static_cast<uint16_t>(q[s]);
    lo += reinterpret_cast<Half>((Half{} + static_cast<uint16_t>(f & 0xFFFF)) & bit) != 0 ? v : Half{};
    hi += reinterpret_cast<Half>((Half{} + static_cast<uint16_t>(f >> 16)) & bit) != 0 ? v : Half{};
  }
  std::memcpy(sums, &lo, sizeof(Half));
  std::memcpy(sums + 16, &hi, sizeof(Half));
}

// The integer test of one checkpoint: bit j set when lane j's residue t_j = (sums_j - low) mod
// 2^16 is at least goal_j - shift, that threshold saturated to [0, 65535] (above 65535 only t_j =
// 65535 passes: a looser test, never a stricter one).
inline uint32_t goal_bits(const uint16_t* sums, uint16_t low, int32_t shift, const int32_t* goal) {
  uint32_t bits = 0;
  for (int32_t j = 0; j < kScoringBatch; ++j) {
    const int32_t t = static_cast<uint16_t>(sums[j] - low);
    int32_t threshold = goal[j] - shift;
    threshold = threshold < 0 ? 0 : (threshold > 65535 ? 65535 : threshold);
    if (t >= threshold) bits |= 1u << j;
  }
  return bits;
}

// The residue base and the constant of the integer test (lane j passes when t_j >= goal_j -
// shift) at checkpoint k, or at the end of the list.
inline uint16_t check_low(const ScreenList& v, int64_t k, bool last) { return last ? v.end_low : v.check_low[k]; }
inline int32_t check_shift(const ScreenList& v, int64_t k, bool last) {
  return (last ? 0 : v.check_add[k]) + v.units + 2;
}

// One batch: the class's screening list in steps of kScreenCheck entries, the test at each.
// residues (null, or kScoringBatch entries) gets the residues at the end of the list when a lane
// passes there.
inline uint32_t screen_batch_body(const ScreenList& v, const uint32_t* fire, const int32_t* goal, uint32_t valid,
                                  uint16_t* residues) {
  uint16_t sums[kScoringBatch] = {};
  for (int64_t e = 0, k = 0;; ++k) {
    const int64_t stop = v.count < e + kScreenCheck ? v.count : e + kScreenCheck;
    add_screen_sums(v.list + e, stop - e, v.q, fire, sums);
    e = stop;
    const bool last = e == v.count;
    const uint32_t bits = goal_bits(sums, check_low(v, k, last), check_shift(v, k, last), goal) & valid;
    if (last && bits != 0 && residues != nullptr) {
      for (int32_t j = 0; j < kScoringBatch; ++j) residues[j] = static_cast<uint16_t>(sums[j] - v.end_low);
    }
    if (last || bits == 0) return bits;
  }
}

inline uint64_t screen_class_body(const ScreenList& v, int32_t batches, const uint32_t* const* fire,
                                  const int32_t* const* goal, const uint32_t* valid, uint16_t* residues) {
  uint64_t bits = 0;
  for (int32_t b = 0; b < batches; ++b) {
    uint16_t* r = residues != nullptr ? residues + kScoringBatch * b : nullptr;
    bits |= static_cast<uint64_t>(screen_batch_body(v, fire[b], goal[b], valid[b], r)) << (32 * b);
  }
  return bits;
}

inline bool any_lane_passes_body(const double* score, const double* background, const double* cutoff, double min_margin,
                                 double min_score) {
  LaneMask any = {};
  const Batch margin = Batch{} + min_margin, floor = Batch{} + min_score;
  for (int32_t v = 0; v < kVectors; ++v) {
    Batch s, bg, cut;
    std::memcpy(&s, score + kLanes * v, sizeof(Batch));
    std::memcpy(&bg, background + kLanes * v, sizeof(Batch));
    std::memcpy(&cut, cutoff + kLanes * v, sizeof(Batch));
    any |= (s - bg > margin) & (s >= floor) & (s >= cut);
  }
  return (any[0] | any[1] | any[2] | any[3]) != 0;
}

}  // namespace
}  // namespace lmb::detail

// The portable bodies under one ISA's names (scoring_generic.cc, scoring_avx2.cc): the
// accumulations (LMB_DEFINE_SCORING_ACCUMULATIONS) and the rest (LMB_DEFINE_SCORING_KERNELS_REST).
#define LMB_DEFINE_SCORING_KERNELS(isa) \
  LMB_DEFINE_SCORING_ACCUMULATIONS(isa) \
  LMB_DEFINE_SCORING_KERNELS_REST(isa)
#define LMB_DEFINE_SCORING_ACCUMULATIONS(isa)                                                                      \
  void accumulate_lanes_##isa(double bias, const int32_t* stumps, int64_t count, const DenseStump* dense,          \
                              const uint32_t* fire, double* out) {                                                 \
    accumulate_lanes_body(bias, stumps, count, dense, fire, out);                                                  \
  }                                                                                                                \
  void accumulate_two_##isa(double bias0, const int32_t* stumps0, int64_t count0, double bias1,                    \
                            const int32_t* stumps1, int64_t count1, const DenseStump* dense, const uint32_t* fire, \
                            double* out0, double* out1) {                                                          \
    accumulate_lanes_body(bias0, stumps0, count0, dense, fire, out0);                                              \
    accumulate_lanes_body(bias1, stumps1, count1, dense, fire, out1);                                              \
  }                                                                                                                \
  void accumulate_groups_##isa(const GroupItem* items, int32_t n, const DenseStump* dense, const uint32_t* fire) { \
    accumulate_groups_body(items, n, dense, fire);                                                                 \
  }
#define LMB_DEFINE_SCORING_KERNELS_REST(isa)                                                                         \
  void fire_masks_##isa(const DenseStump* stumps, size_t num_stumps, const uint8_t* values, size_t stride,           \
                        uint32_t* fire) {                                                                            \
    fire_masks_body(stumps, num_stumps, values, stride, fire);                                                       \
  }                                                                                                                  \
  uint64_t screen_class_##isa(const ScreenList& list, int32_t batches, const uint32_t* const* fire,                  \
                              const int32_t* const* goal, const uint32_t* valid, uint16_t* residues) {               \
    return screen_class_body(list, batches, fire, goal, valid, residues);                                            \
  }                                                                                                                  \
  bool any_lane_passes_##isa(const double* score, const double* background, const double* cutoff, double min_margin, \
                             double min_score) {                                                                     \
    return any_lane_passes_body(score, background, cutoff, min_margin, min_score);                                   \
  }
