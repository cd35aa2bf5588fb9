// Scoring kernels with AVX-512 (compiled with -mavx512f -mavx512bw -mavx512dq -mavx512vl; x86-64
// only): 8 doubles a register with the fire bits as blend masks, and the screening's 32 uint16
// lanes in one register with the fire bits as the masks of its additions.
#if defined(__x86_64__)
#include <immintrin.h>

#include "infer/simd/scoring_kernels.h"

namespace lmb::detail {

namespace {

// Two classes at once (four 8-lane registers each): each register takes its fire bits as the
// blend mask directly (one blend and one add per 8 lanes). The common length of the two stump
// lists runs in one loop, so that the two classes' chains of dependent additions overlap; then
// the rest of each list.
struct Lanes512 {
  __m512d acc[4];
};

// Byte v of a stump's fire bits (lanes 8 v .. 8 v + 7; x86 is little-endian), read from memory
// straight into a mask register. Shifting the uint32 instead lets GCC keep it in a mask register
// and shift there (kshiftrd), a chain of dependent mask operations that made accumulate_two ~5%
// slower than these independent loads.
[[gnu::always_inline]] inline __mmask8 fire_byte(const uint32_t* fire, int32_t s, int32_t v) {
  return reinterpret_cast<const uint8_t*>(fire + s)[v];
}

[[gnu::always_inline]] inline void add_stump(Lanes512& l, int32_t s, const DenseStump* dense, const uint32_t* fire) {
  const __m512d a = _mm512_set1_pd(dense[s].above), b = _mm512_set1_pd(dense[s].below);
  for (int32_t v = 0; v < 4; ++v) {
    l.acc[v] = _mm512_add_pd(l.acc[v], _mm512_mask_blend_pd(fire_byte(fire, s, v), b, a));
  }
}

[[gnu::always_inline]] inline __m512d add_group(__m512d acc, const GroupItem& item, int64_t e, const DenseStump* dense,
                                                const uint32_t* fire) {
  const int32_t s = item.stumps[e];
  const __mmask8 bits = fire_byte(fire, s, item.group);
  return _mm512_add_pd(acc, _mm512_mask_blend_pd(bits, _mm512_set1_pd(dense[s].below), _mm512_set1_pd(dense[s].above)));
}

// Up to four (class, 8-lane group) items at once, one register each (four independent chains of
// additions).
void groups4(const GroupItem* items, int32_t n, const DenseStump* dense, const uint32_t* fire) {
  __m512d acc[4];
  int64_t common = INT64_MAX;
  for (int32_t i = 0; i < n; ++i) {
    acc[i] = _mm512_set1_pd(items[i].bias);
    common = items[i].count < common ? items[i].count : common;
  }
  if (n == 4) {
    for (int64_t e = 0; e < common; ++e) {
      acc[0] = add_group(acc[0], items[0], e, dense, fire);
      acc[1] = add_group(acc[1], items[1], e, dense, fire);
      acc[2] = add_group(acc[2], items[2], e, dense, fire);
      acc[3] = add_group(acc[3], items[3], e, dense, fire);
    }
  } else {
    common = 0;
  }
  for (int32_t i = 0; i < n; ++i) {
    for (int64_t e = common; e < items[i].count; ++e) acc[i] = add_group(acc[i], items[i], e, dense, fire);
    _mm512_storeu_pd(items[i].out, acc[i]);
  }
}

// The integer test of one checkpoint (goal_bits of scoring_body.h) for 32 lanes. The goals come in
// the order that packus (which interleaves its operands by 128-bit lane) undoes: goal_lo[4 i + r]
// = goal[8 i + r], goal_hi[4 i + r] = goal[8 i + 4 + r] (permuted_goals); packus saturates the
// thresholds to [0, 65535] as goal_bits does.
[[gnu::always_inline]] inline uint32_t goal_bits(__m512i sums, uint16_t low, int32_t shift, __m512i goal_lo,
                                                 __m512i goal_hi) {
  const __m512i t = _mm512_sub_epi16(sums, _mm512_set1_epi16(static_cast<int16_t>(low)));
  const __m512i s = _mm512_set1_epi32(shift);
  const __m512i threshold = _mm512_packus_epi32(_mm512_sub_epi32(goal_lo, s), _mm512_sub_epi32(goal_hi, s));
  return static_cast<uint32_t>(_mm512_cmpge_epu16_mask(t, threshold));
}

[[gnu::always_inline]] inline void permuted_goals(const int32_t* goal, __m512i* lo, __m512i* hi) {
  const __m512i first = _mm512_setr_epi32(0, 1, 2, 3, 8, 9, 10, 11, 16, 17, 18, 19, 24, 25, 26, 27);
  const __m512i second = _mm512_add_epi32(first, _mm512_set1_epi32(4));
  const __m512i g0 = _mm512_loadu_si512(goal), g1 = _mm512_loadu_si512(goal + 16);
  *lo = _mm512_permutex2var_epi32(g0, first, g1);
  *hi = _mm512_permutex2var_epi32(g0, second, g1);
}

}  // namespace

void accumulate_two_avx512(double bias0, const int32_t* stumps0, int64_t count0, double bias1, const int32_t* stumps1,
                           int64_t count1, const DenseStump* dense, const uint32_t* fire, double* out0, double* out1) {
  Lanes512 p, q;
  for (int32_t v = 0; v < 4; ++v) {
    p.acc[v] = _mm512_set1_pd(bias0);
    q.acc[v] = _mm512_set1_pd(bias1);
  }
  const int64_t common = count0 < count1 ? count0 : count1;
  for (int64_t e = 0; e < common; ++e) {
    add_stump(p, stumps0[e], dense, fire);
    add_stump(q, stumps1[e], dense, fire);
  }
  for (int64_t e = common; e < count0; ++e) add_stump(p, stumps0[e], dense, fire);
  for (int64_t e = common; e < count1; ++e) add_stump(q, stumps1[e], dense, fire);
  for (int32_t v = 0; v < 4; ++v) {
    _mm512_storeu_pd(out0 + 8 * v, p.acc[v]);
    _mm512_storeu_pd(out1 + 8 * v, q.acc[v]);
  }
}

void accumulate_lanes_avx512(double bias, const int32_t* stumps, int64_t count, const DenseStump* dense,
                             const uint32_t* fire, double* out) {
  double unused[kScoringBatch];
  accumulate_two_avx512(bias, stumps, count, 0.0, nullptr, 0, dense, fire, out, unused);
}

void accumulate_groups_avx512(const GroupItem* items, int32_t n, const DenseStump* dense, const uint32_t* fire) {
  for (int32_t i = 0; i < n; i += 4) groups4(items + i, n - i < 4 ? n - i : 4, dense, fire);
}

// One class in `batches` (1 or 2) batches at once, 32 uint16 lanes a batch in one register: one
// masked addition a stump and batch (the fire bits are the mask), the integer test at every
// checkpoint (the class is dropped when no valid lane of any batch passes) and at the end.
uint64_t screen_class_avx512(const ScreenList& v, int32_t batches, const uint32_t* const* fire,
                             const int32_t* const* goal, const uint32_t* valid, uint16_t* residues) {
  const uint32_t* fire0 = fire[0];
  const uint32_t* fire1 = fire[batches > 1 ? 1 : 0];
  uint32_t valid0 = valid[0], valid1 = batches > 1 ? valid[1] : 0;
  __m512i goal_lo[2], goal_hi[2];
  permuted_goals(goal[0], &goal_lo[0], &goal_hi[0]);
  permuted_goals(goal[batches > 1 ? 1 : 0], &goal_lo[1], &goal_hi[1]);
  __m512i acc0 = _mm512_setzero_si512(), acc1 = _mm512_setzero_si512();
  // Two batches share a pass until one of them fails a checkpoint in every lane (its bound only
  // falls from then on, and its bits are 0, as screening it alone gives); the other goes on
  // alone as batch 0 of the loop, its bits shifted back to their place at the end.
  bool pair = batches > 1;
  int32_t out_shift = 0;
  for (int64_t e = 0, k = 0;; ++k) {
    const int64_t stop = v.count < e + kScreenCheck ? v.count : e + kScreenCheck;
    if (pair) {
      for (; e < stop; ++e) {
        const uint32_t s = v.list[e];
        const __m512i step_q = _mm512_set1_epi16(v.q[s]);
        acc0 = _mm512_mask_add_epi16(acc0, static_cast<__mmask32>(fire0[s]), acc0, step_q);
        acc1 = _mm512_mask_add_epi16(acc1, static_cast<__mmask32>(fire1[s]), acc1, step_q);
      }
    } else {
      for (; e < stop; ++e) {
        const uint32_t s = v.list[e];
        acc0 = _mm512_mask_add_epi16(acc0, static_cast<__mmask32>(fire0[s]), acc0, _mm512_set1_epi16(v.q[s]));
      }
    }
    const bool last = e == v.count;
    const uint16_t low = last ? v.end_low : v.check_low[k];
    const int32_t shift = (last ? 0 : v.check_add[k]) + v.units + 2;
    const uint32_t bits0 = goal_bits(acc0, low, shift, goal_lo[0], goal_hi[0]) & valid0;
    // At the end, the residues of a batch with a lane that passes (out_shift / 32: batch 0's slot).
    const auto store = [&](__m512i acc, int32_t slot) {
      _mm512_storeu_si512(residues + kScoringBatch * slot,
                          _mm512_sub_epi16(acc, _mm512_set1_epi16(static_cast<int16_t>(low))));
    };
    if (!pair) {
      if (last && bits0 != 0 && residues != nullptr) store(acc0, out_shift / 32);
      if (last || bits0 == 0) return static_cast<uint64_t>(bits0) << out_shift;
      continue;
    }
    const uint32_t bits1 = goal_bits(acc1, low, shift, goal_lo[1], goal_hi[1]) & valid1;
    if (last && residues != nullptr) {
      if (bits0 != 0) store(acc0, 0);
      if (bits1 != 0) store(acc1, 1);
    }
    if (last || (bits0 | bits1) == 0) return bits0 | static_cast<uint64_t>(bits1) << 32;
    if (bits0 == 0) {  // batch 1 goes on alone
      acc0 = acc1;
      fire0 = fire1;
      goal_lo[0] = goal_lo[1];
      goal_hi[0] = goal_hi[1];
      valid0 = valid1;
      out_shift = 32;
      pair = false;
    } else if (bits1 == 0) {
      pair = false;
    }
  }
}

}  // namespace lmb::detail
#endif
