// Scoring kernels with NEON (aarch64 only): the fire masks from byte compares (bit weights summed
// by pairwise additions), each lane's stump output selected by its fire bit (BSL) and added in
// list order, the screening's uint16 sums with masked additions and the saturating narrow of the
// thresholds that goal_bits clamps.
#if defined(__aarch64__)
#include <arm_neon.h>

#include "infer/simd/scoring_kernels.h"

namespace lmb::detail {

namespace {

// out[l] = bias + the stump outputs of lanes first .. first + 2 kPairs - 1 (kPairs double pairs).
template <int32_t kPairs>
[[gnu::always_inline]] inline void accumulate_pairs(double bias, const int32_t* stumps, int64_t count,
                                                    const DenseStump* dense, const uint32_t* fire, int32_t first,
                                                    double* out) {
  const uint64x2_t one_two = vcombine_u64(vcreate_u64(1), vcreate_u64(2));
  float64x2_t acc[kPairs];
  for (int32_t v = 0; v < kPairs; ++v) acc[v] = vdupq_n_f64(bias);
  for (int64_t e = 0; e < count; ++e) {
    const int32_t s = stumps[e];
    const uint64_t f = fire[s] >> first;
    const float64x2_t a = vdupq_n_f64(dense[s].above), b = vdupq_n_f64(dense[s].below);
    for (int32_t v = 0; v < kPairs; ++v) {
      const uint64x2_t selected = vtstq_u64(vdupq_n_u64(f >> (2 * v)), one_two);
      acc[v] = vaddq_f64(acc[v], vbslq_f64(selected, a, b));
    }
  }
  for (int32_t v = 0; v < kPairs; ++v) vst1q_f64(out + 2 * v, acc[v]);
}

// Lane bit weights of 8 uint16 lanes.
inline uint16x8_t lane_bits16() {
  const uint16_t w[8] = {1, 2, 4, 8, 16, 32, 64, 128};
  return vld1q_u16(w);
}

// One batch (screen_batch_body of scoring_body.h).
uint32_t screen_batch(const ScreenList& v, const uint32_t* fire, const int32_t* goal, uint32_t valid,
                      uint16_t* residues) {
  const uint16x8_t bits = lane_bits16();
  uint16x8_t acc[4] = {vdupq_n_u16(0), vdupq_n_u16(0), vdupq_n_u16(0), vdupq_n_u16(0)};
  int32x4_t goals[8];
  for (int32_t i = 0; i < 8; ++i) goals[i] = vld1q_s32(goal + 4 * i);
  for (int64_t e = 0, k = 0;; ++k) {
    const int64_t stop = v.count < e + kScreenCheck ? v.count : e + kScreenCheck;
    for (; e < stop; ++e) {
      const uint32_t s = v.list[e];
      const uint32_t f = fire[s];
      const uint16x8_t q = vdupq_n_u16(static_cast<uint16_t>(v.q[s]));
      for (int32_t g = 0; g < 4; ++g) {
        const uint16x8_t selected = vtstq_u16(vdupq_n_u16(static_cast<uint16_t>((f >> (8 * g)) & 0xFF)), bits);
        acc[g] = vaddq_u16(acc[g], vandq_u16(selected, q));
      }
    }
    const bool last = e == v.count;
    const uint16x8_t low = vdupq_n_u16(last ? v.end_low : v.check_low[k]);
    const int32x4_t shift = vdupq_n_s32((last ? 0 : v.check_add[k]) + v.units + 2);
    uint32_t out = 0;
    for (int32_t g = 0; g < 4; ++g) {
      const uint16x8_t t = vsubq_u16(acc[g], low);
      const uint16x8_t threshold =
          vcombine_u16(vqmovun_s32(vsubq_s32(goals[2 * g], shift)), vqmovun_s32(vsubq_s32(goals[2 * g + 1], shift)));
      const uint16x8_t pass = vandq_u16(vcgeq_u16(t, threshold), bits);
      out |= static_cast<uint32_t>(vaddvq_u16(pass)) << (8 * g);
    }
    out &= valid;
    if (last && out != 0 && residues != nullptr) {
      for (int32_t g = 0; g < 4; ++g) vst1q_u16(residues + 8 * g, vsubq_u16(acc[g], low));
    }
    if (last || out == 0) return out;
  }
}

}  // namespace

void fire_masks_neon(const DenseStump* stumps, size_t num_stumps, const uint8_t* values, size_t stride,
                     uint32_t* fire) {
  const uint8_t w[16] = {1, 2, 4, 8, 16, 32, 64, 128, 1, 2, 4, 8, 16, 32, 64, 128};
  const uint8x16_t weights = vld1q_u8(w);
  for (size_t s = 0; s < num_stumps; ++s) {
    const uint8_t* v = values + static_cast<size_t>(stumps[s].used) * stride;
    const uint8x16_t theta = vdupq_n_u8(stumps[s].theta);
    const uint8x16_t g0 = vandq_u8(vcgtq_u8(vld1q_u8(v), theta), weights);
    const uint8x16_t g1 = vandq_u8(vcgtq_u8(vld1q_u8(v + 16), theta), weights);
    // Pairwise sums, three times: byte i of the result sums the weights of lanes 8 i .. 8 i + 7.
    uint8x16_t p = vpaddq_u8(g0, g1);
    p = vpaddq_u8(p, p);
    p = vpaddq_u8(p, p);
    fire[s] = vgetq_lane_u32(vreinterpretq_u32_u8(p), 0);
  }
}

void accumulate_lanes_neon(double bias, const int32_t* stumps, int64_t count, const DenseStump* dense,
                           const uint32_t* fire, double* out) {
  accumulate_pairs<kScoringBatch / 2>(bias, stumps, count, dense, fire, 0, out);
}

void accumulate_two_neon(double bias0, const int32_t* stumps0, int64_t count0, double bias1, const int32_t* stumps1,
                         int64_t count1, const DenseStump* dense, const uint32_t* fire, double* out0, double* out1) {
  accumulate_lanes_neon(bias0, stumps0, count0, dense, fire, out0);
  accumulate_lanes_neon(bias1, stumps1, count1, dense, fire, out1);
}

void accumulate_groups_neon(const GroupItem* items, int32_t n, const DenseStump* dense, const uint32_t* fire) {
  for (int32_t i = 0; i < n; ++i) {
    accumulate_pairs<4>(items[i].bias, items[i].stumps, items[i].count, dense, fire, 8 * items[i].group, items[i].out);
  }
}

uint64_t screen_class_neon(const ScreenList& list, int32_t batches, const uint32_t* const* fire,
                           const int32_t* const* goal, const uint32_t* valid, uint16_t* residues) {
  uint64_t bits = 0;
  for (int32_t b = 0; b < batches; ++b) {
    uint16_t* r = residues != nullptr ? residues + kScoringBatch * b : nullptr;
    bits |= static_cast<uint64_t>(screen_batch(list, fire[b], goal[b], valid[b], r)) << (32 * b);
  }
  return bits;
}

bool any_lane_passes_neon(const double* score, const double* background, const double* cutoff, double min_margin,
                          double min_score) {
  const float64x2_t margin = vdupq_n_f64(min_margin), floor = vdupq_n_f64(min_score);
  uint64x2_t any = vdupq_n_u64(0);
  for (int32_t v = 0; v < kScoringBatch / 2; ++v) {
    const float64x2_t s = vld1q_f64(score + 2 * v);
    const float64x2_t bg = vld1q_f64(background + 2 * v);
    const float64x2_t cut = vld1q_f64(cutoff + 2 * v);
    const uint64x2_t pass =
        vandq_u64(vandq_u64(vcgtq_f64(vsubq_f64(s, bg), margin), vcgeq_f64(s, floor)), vcgeq_f64(s, cut));
    any = vorrq_u64(any, pass);
  }
  return (vgetq_lane_u64(any, 0) | vgetq_lane_u64(any, 1)) != 0;
}

}  // namespace lmb::detail
#endif
