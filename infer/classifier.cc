#include "infer/classifier.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "common/cpu_dispatch.h"
#include "common/error.h"

namespace lmb {

void ClassifierOptions::check() const {
  LMB_CHECK(top_k >= 1 && top_k <= 1000000, "classifier options: top_k = " << top_k << " must be in 1..1000000");
  LMB_CHECK(!std::isnan(min_margin) && min_margin != std::numeric_limits<double>::infinity(),
            "classifier options: min_margin = " << min_margin << " must be a number below +inf");
  LMB_CHECK(!std::isnan(min_score) && min_score != std::numeric_limits<double>::infinity(),
            "classifier options: min_score = " << min_score << " must be a number below +inf");
}

namespace {
const Model& checked(const std::shared_ptr<const Model>& model) {
  LMB_CHECK(model != nullptr, "classifier: null model");
  return *model;
}
}  // namespace

Classifier::Classifier(std::shared_ptr<const Model> model, const ClassifierOptions& options)
    : model_(std::move(model)), options_(options), context_(checked(model_).regions(), checked(model_).num_words()) {
  options_.check();
  const size_t U = model_->used_dims().size();
  values_.assign(U * kBatch, 0);
  word_values_.resize(U);
  class_out_.resize(2 * kBatch);
  all_classes_.resize(static_cast<size_t>(model_->num_classes()));
  for (int32_t c = 0; c < model_->num_classes(); ++c) all_classes_[c] = c;
  lanes_.resize(kBatch);
  cutoff_.resize(kBatch);
  cutoff_score_.assign(kBatch, -std::numeric_limits<double>::infinity());
}

void Classifier::index_frame(const FrameKeypoints& frame, const std::string& where) { context_.reset(frame, where); }

void Classifier::compute_used_values(int32_t k, const uint8_t* descriptor, uint8_t* values) const {
  context_.compute_dims(k, model_->used_plan(), descriptor, values);
}

void Classifier::dense_scores(const uint8_t* values, double* scores) const {
  const Model& m = *model_;
  const std::vector<double>& bias = m.data().bias;
  std::copy(bias.begin(), bias.end(), scores);
  const std::vector<Model::DenseStump>& stumps = m.dense_stumps();
  const int64_t* begin = m.stump_class_begin().data();
  const int32_t* classes = m.stump_classes().data();
  for (size_t s = 0; s < stumps.size(); ++s) {
    const Model::DenseStump& st = stumps[s];
    const double h = values[st.used] > st.theta ? st.above : st.below;
    for (int64_t e = begin[s]; e < begin[s + 1]; ++e) scores[classes[e]] += h;
  }
}

double Classifier::class_score(const uint8_t* values, int32_t cls) const {
  const Model& m = *model_;
  double total = m.data().bias[cls];
  const Model::DenseStump* st = m.class_stumps().data();
  const int64_t end = m.class_stump_begin()[cls + 1];
  for (int64_t e = m.class_stump_begin()[cls]; e < end; ++e) {
    total += values[st[e].used] > st[e].theta ? st[e].above : st[e].below;
  }
  return total;
}

namespace {

// 4 lanes (one AVX2 register, two SSE2 ones).
using Batch = double __attribute__((vector_size(32), aligned(8)));
using LaneMask = int64_t __attribute__((vector_size(32), aligned(8)));
constexpr int32_t kLanes = 4;
constexpr int32_t kVectors = Classifier::kBatch / kLanes;
static_assert(Classifier::kBatch == 32, "a batch's fire bits of one stump are a uint32");

// fire[s] bit j = lane j's value of stump s's dim is above the stump's threshold. values: kBatch
// lanes of used dim u at values[u * stride]. Cloned for AVX2 (common/cpu_dispatch.h).
LMB_CLONES_AVX2 void fire_masks_impl(const Model::DenseStump* stumps, size_t num_stumps, const uint8_t* values,
                                     size_t stride, uint32_t* fire) {
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

// out[j] = bias + the outputs of `stumps` (training order) in lane j, for kBatch lanes: lane by
// lane the same additions in the same order as BoostModel::scores; each output is selected (not
// computed) from the stump's two doubles by the lane's fire bit. Cloned for AVX2; IEEE additions
// give the same doubles in both clones.
LMB_CLONES_AVX2 void accumulate_lanes_clones(double bias, const int32_t* stumps, int64_t count,
                                             const Model::DenseStump* dense, const uint32_t* fire, double* out) {
  // Shifting the fire bits left by shift[v] puts bit kLanes * v + i at the sign of lane i.
  LaneMask shift[kVectors];
  for (int32_t v = 0; v < kVectors; ++v) {
    for (int32_t i = 0; i < kLanes; ++i) shift[v][i] = 63 - (kLanes * v + i);
  }
  Batch acc[kVectors];
  for (int32_t v = 0; v < kVectors; ++v) acc[v] = Batch{bias, bias, bias, bias};
  for (int64_t e = 0; e < count; ++e) {
    const int32_t s = stumps[e];
    const LaneMask f = LaneMask{} + static_cast<int64_t>(fire[s]);
    const double above = dense[s].above, below = dense[s].below;
    const Batch a = {above, above, above, above}, b = {below, below, below, below};
    for (int32_t v = 0; v < kVectors; ++v) acc[v] += (f << shift[v]) < 0 ? a : b;
  }
  for (int32_t v = 0; v < kVectors; ++v) std::memcpy(out + kLanes * v, &acc[v], sizeof(Batch));
}

#if defined(__x86_64__)
// The same with AVX-512, for two classes at once (four 8-lane registers each): each register takes
// its fire bits as the blend mask directly (one blend and one add per 8 lanes, against a shift, a
// blend and an add per 4 with AVX2). The common length of the two stump lists runs in one loop,
// so that the two classes' chains of dependent additions overlap; then the rest of each list.
struct Lanes512 {
  __m512d acc[4];
};

__attribute__((target("avx512f"), always_inline)) inline void add_stump_avx512(Lanes512& l, int32_t s,
                                                                               const Model::DenseStump* dense,
                                                                               const uint32_t* fire) {
  const uint32_t f = fire[s];
  const __m512d a = _mm512_set1_pd(dense[s].above), b = _mm512_set1_pd(dense[s].below);
  for (int32_t v = 0; v < 4; ++v) {
    const __mmask8 bits = static_cast<__mmask8>(f >> (8 * v));
    l.acc[v] = _mm512_add_pd(l.acc[v], _mm512_mask_blend_pd(bits, b, a));
  }
}

__attribute__((target("avx512f"))) void accumulate_two_avx512(double bias0, const int32_t* stumps0, int64_t count0,
                                                              double bias1, const int32_t* stumps1, int64_t count1,
                                                              const Model::DenseStump* dense, const uint32_t* fire,
                                                              double* out0, double* out1) {
  Lanes512 p, q;
  for (int32_t v = 0; v < 4; ++v) {
    p.acc[v] = _mm512_set1_pd(bias0);
    q.acc[v] = _mm512_set1_pd(bias1);
  }
  const int64_t common = std::min(count0, count1);
  for (int64_t e = 0; e < common; ++e) {
    add_stump_avx512(p, stumps0[e], dense, fire);
    add_stump_avx512(q, stumps1[e], dense, fire);
  }
  for (int64_t e = common; e < count0; ++e) add_stump_avx512(p, stumps0[e], dense, fire);
  for (int64_t e = common; e < count1; ++e) add_stump_avx512(q, stumps1[e], dense, fire);
  for (int32_t v = 0; v < 4; ++v) {
    _mm512_storeu_pd(out0 + 8 * v, p.acc[v]);
    _mm512_storeu_pd(out1 + 8 * v, q.acc[v]);
  }
}

__attribute__((target("avx512f"), always_inline)) inline __m512d add_group_avx512(
    __m512d acc, const detail::GroupItem& item, int64_t e, const Model::DenseStump* dense, const uint32_t* fire) {
  const int32_t s = item.stumps[e];
  const __mmask8 bits = static_cast<__mmask8>(fire[s] >> (8 * item.group));
  return _mm512_add_pd(acc, _mm512_mask_blend_pd(bits, _mm512_set1_pd(dense[s].below), _mm512_set1_pd(dense[s].above)));
}

// Up to four (class, 8-lane group) items at once, one AVX-512 register each (four independent
// chains of additions): out[i][l] = items[i].bias + the outputs of items[i]'s stumps in lane
// 8 group + l, in list order (the same additions as accumulate_lanes).
__attribute__((target("avx512f"))) void accumulate_groups_avx512(const detail::GroupItem* items, int32_t n,
                                                                 const Model::DenseStump* dense, const uint32_t* fire) {
  __m512d acc[4];
  int64_t common = std::numeric_limits<int64_t>::max();
  for (int32_t i = 0; i < n; ++i) {
    acc[i] = _mm512_set1_pd(items[i].bias);
    common = std::min(common, items[i].count);
  }
  auto add = [&](int32_t i, int64_t e) __attribute__((target("avx512f"))) {
    acc[i] = add_group_avx512(acc[i], items[i], e, dense, fire);
  };
  if (n == 4) {
    for (int64_t e = 0; e < common; ++e) {
      add(0, e);
      add(1, e);
      add(2, e);
      add(3, e);
    }
  } else {
    common = 0;
  }
  for (int32_t i = 0; i < n; ++i) {
    for (int64_t e = common; e < items[i].count; ++e) add(i, e);
    _mm512_storeu_pd(items[i].out, acc[i]);
  }
}

// A class's screening data (Model::screen_step and the following accessors).
struct ScreenView {
  ScreenView(const Model& model, int32_t cls)
      : q(model.screen_q().data()),
        list(model.screen_list().data() + model.class_stump_begin()[cls]),
        count(model.class_stump_begin()[cls + 1] - model.class_stump_begin()[cls]),
        check_low(model.screen_check_low().data() + model.screen_check_begin()[cls]),
        check_add(model.screen_check_add().data() + model.screen_check_begin()[cls]),
        end_low(model.screen_low()[cls]),
        units(model.screen_units()[cls]) {}
  // The residue base and the added steps at checkpoint k, or at the end of the list.
  uint16_t low(int64_t k, bool last) const { return last ? end_low : check_low[k]; }
  int32_t add(int64_t k, bool last) const { return last ? 0 : check_add[k]; }

  const int16_t* q;
  const uint16_t* list;
  int64_t count;
  const uint16_t* check_low;
  const int32_t* check_add;
  uint16_t end_low;
  int32_t units;
  // The integer test's constant at checkpoint k: lane j passes when t_j >= goal_j - shift.
  int32_t shift(int64_t k, bool last) const { return add(k, last) + units + 2; }
};

// The integer test of one checkpoint (Model::kScreenCheck): bit j set when lane j's residue
// t_j = (sums_j - low) mod 2^16 is at least goal_j - shift, that threshold saturated to
// [0, 65535] (above 65535 only t_j = 65535 passes: a looser test, never a stricter one). The goals
// come in the order that packus (which interleaves its operands by 128-bit lane) undoes:
// goal_lo[4 i + r] = goal[8 i + r], goal_hi[4 i + r] = goal[8 i + 4 + r] (permuted_goals).
__attribute__((target("avx512f,avx512bw"), always_inline)) inline uint32_t goal_bits_avx512(__m512i sums, uint16_t low,
                                                                                            int32_t shift,
                                                                                            __m512i goal_lo,
                                                                                            __m512i goal_hi) {
  const __m512i t = _mm512_sub_epi16(sums, _mm512_set1_epi16(static_cast<int16_t>(low)));
  const __m512i s = _mm512_set1_epi32(shift);
  const __m512i threshold = _mm512_packus_epi32(_mm512_sub_epi32(goal_lo, s), _mm512_sub_epi32(goal_hi, s));
  return static_cast<uint32_t>(_mm512_cmpge_epu16_mask(t, threshold));
}

__attribute__((target("avx512f"), always_inline)) inline void permuted_goals(const int32_t* goal, __m512i* lo,
                                                                             __m512i* hi) {
  const __m512i first = _mm512_setr_epi32(0, 1, 2, 3, 8, 9, 10, 11, 16, 17, 18, 19, 24, 25, 26, 27);
  const __m512i second = _mm512_add_epi32(first, _mm512_set1_epi32(4));
  const __m512i g0 = _mm512_loadu_si512(goal), g1 = _mm512_loadu_si512(goal + 16);
  *lo = _mm512_permutex2var_epi32(g0, first, g1);
  *hi = _mm512_permutex2var_epi32(g0, second, g1);
}

// Screening of one class in `batches` (1 or 2) batches at once, 32 uint16 lanes a batch in one
// register: one masked addition a stump and batch (the fire bits are the mask), the integer
// test at every checkpoint (the class is dropped when no valid lane of any batch passes) and at
// the end. Lane j of batch b is bit 32 b + j of the result.
__attribute__((target("avx512f,avx512bw"))) uint64_t screen_class_avx512(const Model& model, int32_t cls,
                                                                         int32_t batches, const uint32_t* const* fire,
                                                                         const int32_t* const* goal,
                                                                         const uint32_t* valid) {
  const ScreenView v(model, cls);
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
    const int64_t stop = std::min(v.count, e + Model::kScreenCheck);
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
    const uint16_t low = v.low(k, last);
    const int32_t shift = v.shift(k, last);
    const uint32_t bits0 = goal_bits_avx512(acc0, low, shift, goal_lo[0], goal_hi[0]) & valid0;
    if (!pair) {
      if (last || bits0 == 0) return static_cast<uint64_t>(bits0) << out_shift;
      continue;
    }
    const uint32_t bits1 = goal_bits_avx512(acc1, low, shift, goal_lo[1], goal_hi[1]) & valid1;
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
#endif

#if defined(__x86_64__)
const bool kHasAvx512 = (__builtin_cpu_init(), __builtin_cpu_supports("avx512f"));
const bool kHasAvx512bw = (__builtin_cpu_init(), __builtin_cpu_supports("avx512bw"));
#endif

// Screening sums of stumps[0, count) added into sums (modulo 2^16) with 16-lane vectors: a lane
// adds q where its fire bit is set (its bit of the broadcast mask ANDed with the lane's own bit).
LMB_CLONES_AVX2 void add_screen_sums(const uint16_t* stumps, int64_t count, const int16_t* q, const uint32_t* fire,
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

// goal_bits_avx512 lane by lane.
uint32_t goal_bits(const uint16_t* sums, uint16_t low, int32_t shift, const int32_t* goal) {
  uint32_t bits = 0;
  for (int32_t j = 0; j < Classifier::kBatch; ++j) {
    const int32_t t = static_cast<uint16_t>(sums[j] - low);
    const int32_t threshold = std::clamp(goal[j] - shift, 0, 65535);
    if (t >= threshold) bits |= 1u << j;
  }
  return bits;
}

}  // namespace

// (The target_clones functions above stay in the anonymous namespace: their IFUNC symbols would
// otherwise be exported from the shared library whatever the visibility.)
namespace detail {

void fire_masks(const Model::DenseStump* stumps, size_t num_stumps, const uint8_t* values, size_t stride,
                uint32_t* fire) {
  fire_masks_impl(stumps, num_stumps, values, stride, fire);
}

void accumulate_lanes_generic(double bias, const int32_t* stumps, int64_t count, const Model::DenseStump* dense,
                              const uint32_t* fire, double* out) {
  accumulate_lanes_clones(bias, stumps, count, dense, fire, out);
}

void accumulate_lanes(double bias, const int32_t* stumps, int64_t count, const Model::DenseStump* dense,
                      const uint32_t* fire, double* out) {
#if defined(__x86_64__)
  if (kHasAvx512) {
    double unused[Classifier::kBatch];
    return accumulate_two_avx512(bias, stumps, count, 0.0, nullptr, 0, dense, fire, out, unused);
  }
#endif
  accumulate_lanes_clones(bias, stumps, count, dense, fire, out);
}

void accumulate_two(double bias0, const int32_t* stumps0, int64_t count0, double bias1, const int32_t* stumps1,
                    int64_t count1, const Model::DenseStump* dense, const uint32_t* fire, double* out0, double* out1) {
#if defined(__x86_64__)
  if (kHasAvx512) {
    return accumulate_two_avx512(bias0, stumps0, count0, bias1, stumps1, count1, dense, fire, out0, out1);
  }
#endif
  accumulate_lanes_clones(bias0, stumps0, count0, dense, fire, out0);
  accumulate_lanes_clones(bias1, stumps1, count1, dense, fire, out1);
}

void accumulate_groups(const GroupItem* items, int32_t n, const Model::DenseStump* dense, const uint32_t* fire) {
#if defined(__x86_64__)
  if (kHasAvx512) {
    for (int32_t i = 0; i < n; i += 4) accumulate_groups_avx512(items + i, std::min(4, n - i), dense, fire);
    return;
  }
#endif
  double lanes[Classifier::kBatch];
  for (int32_t i = 0; i < n; ++i) {
    accumulate_lanes_clones(items[i].bias, items[i].stumps, items[i].count, dense, fire, lanes);
    std::memcpy(items[i].out, lanes + 8 * items[i].group, 8 * sizeof(double));
  }
}

uint32_t screen_class_generic(const Model& model, int32_t cls, const uint32_t* fire, const int32_t* goal,
                              uint32_t valid) {
  const ScreenView v(model, cls);
  uint16_t sums[Classifier::kBatch] = {};
  for (int64_t e = 0, k = 0;; ++k) {
    const int64_t stop = std::min(v.count, e + Model::kScreenCheck);
    add_screen_sums(v.list + e, stop - e, v.q, fire, sums);
    e = stop;
    const bool last = e == v.count;
    const uint32_t bits = goal_bits(sums, v.low(k, last), v.shift(k, last), goal) & valid;
    if (last || bits == 0) return bits;
  }
}

uint64_t screen_class(const Model& model, int32_t cls, int32_t batches, const uint32_t* const* fire,
                      const int32_t* const* goal, const uint32_t* valid) {
#if defined(__x86_64__)
  if (kHasAvx512bw) return screen_class_avx512(model, cls, batches, fire, goal, valid);
#endif
  uint64_t bits = 0;
  for (int32_t b = 0; b < batches; ++b) {
    bits |= static_cast<uint64_t>(screen_class_generic(model, cls, fire[b], goal[b], valid[b])) << (32 * b);
  }
  return bits;
}

void screen_goals(const Model& model, const double* background, double min_margin, double min_score, int32_t* goal) {
  const double step = model.screen_step();
  const double safe = step * double{Model::kScreenUnitsLimit / 4};  // 2^27 steps
  const double inf = std::numeric_limits<double>::infinity();
  const bool margin_safe = min_margin == -inf || std::fabs(min_margin) <= safe;
  const bool score_safe = min_score == -inf || std::fabs(min_score) <= safe;
  for (int32_t j = 0; j < Classifier::kBatch; ++j) {
    const double target = std::max(min_margin == -inf ? -inf : background[j] + min_margin, min_score);
    const bool usable = margin_safe && score_safe && std::fabs(background[j]) <= safe && target != -inf;
    goal[j] = usable ? static_cast<int32_t>(std::floor(target / step)) : Model::kScreenPassAll;
  }
}

}  // namespace detail

namespace {

// Whether any of the kBatch lanes passes offer()'s tests with the cutoff one relaxed to >= (as
// finish_batch's scalar loop): most classes pass in no lane. Lanes past the batch's count may
// pass spuriously; the scalar loop skips them.
LMB_CLONES_AVX2 bool any_lane_passes(const double* score, const double* background, const double* cutoff,
                                     double min_margin, double min_score) {
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

// The ranking order: higher score first, then smaller class.
inline bool better(double s, int32_t c, double ts, int32_t tc) { return s > ts || (s == ts && c < tc); }

}  // namespace

void Classifier::offer(int32_t j, int32_t cls, double score, double bg) {
  if (!(score - bg > options_.min_margin && score >= options_.min_score)) return;
  std::vector<Candidate>& lane = lanes_[j];
  const size_t k = static_cast<size_t>(options_.top_k);
  if (lane.size() >= k && !better(score, cls, cutoff_[j].score, cutoff_[j].cls)) return;
  lane.push_back({score, cls});
  if (lane.size() >= 2 * k + 64) {  // keep the best k; later offers must beat the k-th
    const auto by_rank = [](const Candidate& x, const Candidate& y) { return better(x.score, x.cls, y.score, y.cls); };
    std::nth_element(lane.begin(), lane.begin() + static_cast<std::ptrdiff_t>(k - 1), lane.end(), by_rank);
    cutoff_[j] = lane[k - 1];
    cutoff_score_[j] = cutoff_[j].score;
    lane.resize(k);
  }
}

void Classifier::prepare_batch(int32_t b, const uint8_t* values, size_t stride) {
  const Model& m = *model_;
  // Fire masks of every stump (stale value rows of lanes >= count, or of dims the word does not
  // need, give bits no scored class reads).
  const std::vector<Model::DenseStump>& stumps = m.dense_stumps();
  const size_t M = stumps.size();
  if (fire_.size() < (b + 1) * M) fire_.resize((b + 1) * M);
  if (background_.size() < static_cast<size_t>(b + 1) * kBatch) background_.resize(static_cast<size_t>(b + 1) * kBatch);
  uint32_t* fire = fire_.data() + b * M;
  detail::fire_masks(stumps.data(), M, values, stride, fire);
  const int64_t* begin = m.class_stump_begin().data();
  const int32_t C = m.num_classes();
  detail::accumulate_lanes(m.data().bias[C], m.class_stump_index().data() + begin[C], begin[C + 1] - begin[C],
                           stumps.data(), fire, background_.data() + static_cast<size_t>(b) * kBatch);
  if (goal_.size() < background_.size()) goal_.resize(background_.size());
  const double* background = background_.data() + static_cast<size_t>(b) * kBatch;
  double min_score = options_.min_score;
  double lowered[kBatch];
  if (m.has_fusion()) {
    // A fused score is H plus a term of at most fusion_max(): the bound of H need only reach the
    // goals lowered by that much (one screening step more covers the roundings of the sums).
    const double lift = m.fusion_max() + m.screen_step();
    for (int32_t j = 0; j < kBatch; ++j) lowered[j] = background[j] - lift;
    if (min_score != -std::numeric_limits<double>::infinity()) min_score -= lift;
    background = lowered;
  }
  detail::screen_goals(m, background, options_.min_margin, min_score, goal_.data() + static_cast<size_t>(b) * kBatch);
}

namespace {
constexpr int32_t kScreenProbe = 64;
}  // namespace

void Classifier::screen_word(const int32_t* classes, int32_t num, int32_t batches, int32_t keypoints) {
  const Model& m = *model_;
  const size_t M = m.dense_stumps().size();
  if (kept_.size() < static_cast<size_t>(batches)) kept_.resize(static_cast<size_t>(batches));
  for (int32_t b = 0; b < batches; ++b) kept_[b].clear();
  if (!options_.screening) {
    for (int32_t b = 0; b < batches; ++b) {
      for (int32_t i = 0; i < num; ++i) kept_[b].push_back({classes[i], ~0u});
    }
    classes_screened_ += static_cast<int64_t>(num) * batches;
    classes_scored_ += static_cast<int64_t>(num) * batches;
    return;
  }
  // Class by class over the word's batches, two at a time: a class's screening list is read once
  // for two batches. The cutoff test of offer() is left out (the cutoff starts at -inf).
  for (int32_t b = 0; b < batches; b += 2) {
    const int32_t pair = std::min(2, batches - b);
    const uint32_t* fire[2] = {fire_.data() + b * M, fire_.data() + (b + pair - 1) * M};
    const int32_t* goal[2] = {goal_.data() + static_cast<size_t>(b) * kBatch,
                              goal_.data() + static_cast<size_t>(b + pair - 1) * kBatch};
    uint32_t valid[2];
    for (int32_t h = 0; h < pair; ++h) {
      const int32_t count = std::min(kBatch, keypoints - (b + h) * kBatch);
      valid[h] = count == kBatch ? ~0u : (1u << count) - 1;
    }
    // When the screening keeps most classes (a background that rarely wins), it only costs: after
    // kScreenProbe classes with more than 3/4 of them kept, the rest are kept unscreened.
    int32_t kept_count = 0;
    for (int32_t i = 0; i < num; ++i) {
      uint64_t bits = ~0ull;
      if (i < kScreenProbe || 4 * kept_count <= 3 * i) {
        bits = detail::screen_class(m, classes[i], pair, fire, goal, valid);
      }
      kept_count += bits != 0;
      if (bits & 0xFFFFFFFFull) kept_[b].push_back({classes[i], static_cast<uint32_t>(bits)});
      if (pair > 1 && (bits >> 32)) kept_[b + 1].push_back({classes[i], static_cast<uint32_t>(bits >> 32)});
    }
  }
  classes_screened_ += static_cast<int64_t>(num) * batches;
  for (int32_t b = 0; b < batches; ++b) classes_scored_ += static_cast<int64_t>(kept_[b].size());
}

void Classifier::finish_batch(const int32_t* ids, int32_t count, int32_t b) {
  const Model& m = *model_;
  const std::vector<Model::DenseStump>& stumps = m.dense_stumps();
  const uint32_t* fire = fire_.data() + b * stumps.size();
  const double* background = background_.data() + static_cast<size_t>(b) * kBatch;
  const std::vector<double>& bias = m.data().bias;
  const int64_t* begin = m.class_stump_begin().data();
  const int32_t* index = m.class_stump_index().data();
  for (int32_t j = 0; j < count; ++j) {
    lanes_[j].clear();
    cutoff_[j] = {-std::numeric_limits<double>::infinity(), std::numeric_limits<int32_t>::max()};
    cutoff_score_[j] = cutoff_[j].score;
  }
  // The classes kept by the screening: their exact scores in the 8-lane groups where some lane
  // passed the screening (four groups at a time); lanes of the other groups cannot pass and get
  // -inf. Then offered in class order.
  const std::vector<Kept>& kept = kept_[b];
  const int32_t num = static_cast<int32_t>(kept.size());
  if (kept_out_.size() < static_cast<size_t>(num) * kBatch) kept_out_.resize(static_cast<size_t>(num) * kBatch);
  // Classes kept in all four groups go two at a time through accumulate_two.
  groups_.clear();
  int32_t waiting = -1;  // a class kept in all four groups, waiting for a second one
  for (int32_t i = 0; i < num; ++i) {
    const int32_t c = kept[i].cls;
    double* out = kept_out_.data() + static_cast<size_t>(i) * kBatch;
    bool all = true;
    for (int32_t v = 0; v < kBatch / 8; ++v) all = all && ((kept[i].lanes >> (8 * v)) & 0xFFu) != 0;
    if (all && waiting < 0) {
      waiting = i;
    } else if (all) {
      const int32_t c0 = kept[waiting].cls;
      detail::accumulate_two(bias[c0], index + begin[c0], begin[c0 + 1] - begin[c0], bias[c], index + begin[c],
                             begin[c + 1] - begin[c], stumps.data(), fire,
                             kept_out_.data() + static_cast<size_t>(waiting) * kBatch, out);
      waiting = -1;
    } else {
      for (int32_t v = 0; v < kBatch / 8; ++v) {
        if ((kept[i].lanes >> (8 * v)) & 0xFFu) {
          groups_.push_back({bias[c], index + begin[c], begin[c + 1] - begin[c], v, out + 8 * v});
        } else {
          std::fill(out + 8 * v, out + 8 * v + 8, -std::numeric_limits<double>::infinity());
        }
      }
    }
  }
  if (waiting >= 0) {
    const int32_t c0 = kept[waiting].cls;
    detail::accumulate_lanes(bias[c0], index + begin[c0], begin[c0 + 1] - begin[c0], stumps.data(), fire,
                             kept_out_.data() + static_cast<size_t>(waiting) * kBatch);
  }
  detail::accumulate_groups(groups_.data(), static_cast<int32_t>(groups_.size()), stumps.data(), fire);
  const bool fusion = m.has_fusion();
  const double fusion_max = m.fusion_max();
  for (int32_t i = 0; i < num; ++i) {
    const int32_t c = kept[i].cls;
    double* out = kept_out_.data() + static_cast<size_t>(i) * kBatch;
    if (fusion) {
      // H + fusion_max() bounds the fused score from above (rounding is monotone): the descriptor
      // distance is computed only in lanes where that bound passes offer()'s tests.
      double lifted[kBatch];
      for (int32_t j = 0; j < kBatch; ++j) lifted[j] = out[j] + fusion_max;
      if (!any_lane_passes(lifted, background, cutoff_score_.data(), options_.min_margin, options_.min_score)) {
        continue;
      }
      for (int32_t j = 0; j < count; ++j) {
        const double s = lifted[j];
        if (s - background[j] > options_.min_margin && s >= options_.min_score && s >= cutoff_[j].score) {
          out[j] += m.fusion_term(c, descriptors_ + static_cast<int64_t>(ids[j]) * m.descriptor_bytes());
        } else {
          out[j] = -std::numeric_limits<double>::infinity();
        }
      }
    }
    if (!any_lane_passes(out, background, cutoff_score_.data(), options_.min_margin, options_.min_score)) {
      continue;
    }
    for (int32_t j = 0; j < count; ++j) {
      // offer()'s tests, the cutoff one relaxed to >= (inline: most classes fail here).
      const double s = out[j];
      if (s - background[j] > options_.min_margin && s >= options_.min_score && s >= cutoff_[j].score) {
        offer(j, c, s, background[j]);
      }
    }
  }
  const auto by_rank = [](const Candidate& x, const Candidate& y) { return better(x.score, x.cls, y.score, y.cls); };
  for (int32_t j = 0; j < count; ++j) {
    std::vector<Candidate>& lane = lanes_[j];
    const size_t keep = std::min(lane.size(), static_cast<size_t>(options_.top_k));
    std::partial_sort(lane.begin(), lane.begin() + static_cast<std::ptrdiff_t>(keep), lane.end(), by_rank);
    for (size_t i = 0; i < keep; ++i) {
      ClassMatch match;
      match.cls = lane[i].cls;
      match.landmark = m.class_landmark(match.cls);
      match.score = lane[i].score;
      match.background_score = background[j];
      pending_.emplace_back(ids[j], match);
    }
  }
}

KeypointMatches Classifier::classify(const FrameKeypoints& frame, const uint8_t* descriptors, const std::string& where,
                                     double* embedding_ms) {
  using Clock = std::chrono::steady_clock;
  const Model& m = *model_;
  const int32_t n = frame.size();
  LMB_CHECK(n == 0 || descriptors != nullptr, where << ": null descriptors for " << n << " keypoints");
  Clock::duration embedding{0};
  Clock::time_point t0 = Clock::now();
  index_frame(frame, where);
  if (embedding_ms) embedding += Clock::now() - t0;

  // Keypoints grouped by word (inverted file) or all in one group (dense), in keypoint order.
  const bool inverted = options_.use_inverted_file;
  const int32_t groups = inverted ? m.num_words() : 1;
  word_begin_.assign(static_cast<size_t>(groups) + 1, 0);
  for (int32_t k = 0; k < n; ++k) ++word_begin_[(inverted ? frame.word[k] : 0) + 1];
  for (int32_t g = 0; g < groups; ++g) word_begin_[g + 1] += word_begin_[g];
  order_.resize(static_cast<size_t>(n));
  {
    std::vector<int32_t> fill(word_begin_.begin(), word_begin_.end() - 1);
    for (int32_t k = 0; k < n; ++k) order_[fill[inverted ? frame.word[k] : 0]++] = k;
  }

  const size_t U = m.used_dims().size();
  const int32_t bytes = m.descriptor_bytes();
  descriptors_ = descriptors;
  pending_.clear();
  // When the keypoints' plans (their word's, or all used dims) cover most of the used dims, every
  // keypoint's values of all used dims at once, region by region (compute_dims_columns), in the
  // order of order_: column u holds used dim u of every keypoint, so that batch b's lanes are
  // contiguous (frame_stride keeps kBatch readable bytes past the last keypoint).
  int64_t planned = 0;
  for (int32_t g = 0; g < groups; ++g) {
    const int64_t dims = inverted ? m.word_plan(g).size() : static_cast<int64_t>(U);
    planned += dims * (word_begin_[g + 1] - word_begin_[g]);
  }
  const bool columns = 4 * planned >= 3 * static_cast<int64_t>(U) * n;
  const size_t frame_stride = static_cast<size_t>(n) + kBatch;
  if (columns) {
    if (embedding_ms) t0 = Clock::now();
    if (frame_values_.size() < U * frame_stride) frame_values_.resize(U * frame_stride);
    context_.compute_dims_columns(m.used_plan(), order_.data(), n, descriptors, frame_values_.data(), frame_stride);
    if (embedding_ms) embedding += Clock::now() - t0;
  }
  for (int32_t g = 0; g < groups; ++g) {
    const int32_t* classes = all_classes_.data();
    int32_t num = m.num_classes();
    if (inverted) {
      classes = m.word_classes().data() + m.word_class_begin()[g];
      num = m.word_class_begin()[g + 1] - m.word_class_begin()[g];
    }
    // The group's batches: values, fire masks and background scores of each, then the screening
    // of every candidate class over all of them, then each batch's exact scores and ranking.
    const int32_t keypoints = word_begin_[g + 1] - word_begin_[g];
    const int32_t batches = (keypoints + kBatch - 1) / kBatch;
    for (int32_t batch = 0; batch < batches; ++batch) {
      const int32_t b = word_begin_[g] + batch * kBatch;
      const int32_t count = std::min(kBatch, word_begin_[g + 1] - b);
      if (columns) {  // the frame's values, computed above
        prepare_batch(batch, frame_values_.data() + b, frame_stride);
        continue;
      }
      // Only with the inverted file (dense mode always takes the columns): each keypoint's
      // values of only the dims this word's candidates and the background read.
      assert(inverted);
      if (embedding_ms) t0 = Clock::now();
      for (int32_t j = 0; j < count; ++j) {
        const int32_t k = order_[b + j];
        const uint8_t* desc = descriptors + static_cast<int64_t>(k) * bytes;
        uint8_t* lane = values_.data() + j;  // dim-major: value of used dim u at lane[u * kBatch]
        context_.compute_dims(k, m.word_plan(g), desc, word_values_.data());
        const int32_t u0 = m.word_used_begin()[g], u1 = m.word_used_begin()[g + 1];
        const int32_t* used = m.word_used().data() + u0;
        for (int32_t i = 0; i < u1 - u0; ++i) lane[used[i] * kBatch] = word_values_[i];
      }
      if (embedding_ms) embedding += Clock::now() - t0;
      prepare_batch(batch, values_.data(), kBatch);
    }
    screen_word(classes, num, batches, keypoints);
    for (int32_t batch = 0; batch < batches; ++batch) {
      const int32_t b = word_begin_[g] + batch * kBatch;
      finish_batch(order_.data() + b, std::min(kBatch, word_begin_[g + 1] - b), batch);
    }
  }

  // Back to keypoint order (pending_ holds each keypoint's matches best first, contiguously).
  KeypointMatches out;
  out.begin.assign(static_cast<size_t>(n) + 1, 0);
  for (const auto& p : pending_) ++out.begin[p.first + 1];
  for (int32_t k = 0; k < n; ++k) out.begin[k + 1] += out.begin[k];
  out.matches.resize(pending_.size());
  {
    std::vector<int32_t> fill(out.begin.begin(), out.begin.end() - 1);
    for (const auto& p : pending_) out.matches[fill[p.first]++] = p.second;
  }
  if (embedding_ms) *embedding_ms = std::chrono::duration<double, std::milli>(embedding).count();
  return out;
}

}  // namespace lmb
