#include "infer/classifier.h"

#include <algorithm>
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
  LMB_CHECK(top_k >= 1 && top_k <= 1000000, "classifier options: top_k = " << top_k
                                                                          << " must be in 1..1000000");
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
    : model_(std::move(model)),
      options_(options),
      context_(checked(model_).regions(), checked(model_).num_words()) {
  options_.check();
  const size_t U = model_->used_dims().size();
  values_.assign(U * kBatch, 0);
  word_values_.resize(U);
  fire_.resize(model_->dense_stumps().size());
  class_out_.resize(2 * kBatch);
  background_.resize(kBatch);
  all_classes_.resize(static_cast<size_t>(model_->num_classes()));
  for (int32_t c = 0; c < model_->num_classes(); ++c) all_classes_[c] = c;
  lanes_.resize(kBatch);
  cutoff_.resize(kBatch);
  cutoff_score_.assign(kBatch, -std::numeric_limits<double>::infinity());
}

void Classifier::index_frame(const FrameKeypoints& frame, const std::string& where) {
  context_.reset(frame, where);
}

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

// fire[s] bit j = lane j's value of stump s's dim is above the stump's threshold. values: one row
// of kBatch lanes per used dim (dim-major). Cloned for AVX2 (common/cpu_dispatch.h).
LMB_CLONES_AVX2 void fire_masks_impl(const Model::DenseStump* stumps, size_t num_stumps,
                                     const uint8_t* values, uint32_t* fire) {
  using Bytes = uint8_t __attribute__((vector_size(32), aligned(1)));
  using Words = uint64_t __attribute__((vector_size(32), aligned(8)));
  for (size_t s = 0; s < num_stumps; ++s) {
    Bytes v;
    std::memcpy(&v, values + static_cast<size_t>(stumps[s].used) * Classifier::kBatch, sizeof(v));
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
                                             const Model::DenseStump* dense, const uint32_t* fire,
                                             double* out) {
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

__attribute__((target("avx512f"), always_inline)) inline void add_stump_avx512(
    Lanes512& l, int32_t s, const Model::DenseStump* dense, const uint32_t* fire) {
  const uint32_t f = fire[s];
  const __m512d a = _mm512_set1_pd(dense[s].above), b = _mm512_set1_pd(dense[s].below);
  for (int32_t v = 0; v < 4; ++v) {
    const __mmask8 bits = static_cast<__mmask8>(f >> (8 * v));
    l.acc[v] = _mm512_add_pd(l.acc[v], _mm512_mask_blend_pd(bits, b, a));
  }
}

__attribute__((target("avx512f"))) void accumulate_two_avx512(
    double bias0, const int32_t* stumps0, int64_t count0, double bias1, const int32_t* stumps1,
    int64_t count1, const Model::DenseStump* dense, const uint32_t* fire, double* out0,
    double* out1) {
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
#endif

#if defined(__x86_64__)
const bool kHasAvx512 = (__builtin_cpu_init(), __builtin_cpu_supports("avx512f"));
#endif

}  // namespace

// (The target_clones functions above stay in the anonymous namespace: their IFUNC symbols would
// otherwise be exported from the shared library whatever the visibility.)
namespace detail {

void fire_masks(const Model::DenseStump* stumps, size_t num_stumps, const uint8_t* values,
                uint32_t* fire) {
  fire_masks_impl(stumps, num_stumps, values, fire);
}

void accumulate_lanes_generic(double bias, const int32_t* stumps, int64_t count,
                              const Model::DenseStump* dense, const uint32_t* fire, double* out) {
  accumulate_lanes_clones(bias, stumps, count, dense, fire, out);
}

void accumulate_lanes(double bias, const int32_t* stumps, int64_t count,
                      const Model::DenseStump* dense, const uint32_t* fire, double* out) {
#if defined(__x86_64__)
  if (kHasAvx512) {
    double unused[Classifier::kBatch];
    return accumulate_two_avx512(bias, stumps, count, 0.0, nullptr, 0, dense, fire, out, unused);
  }
#endif
  accumulate_lanes_clones(bias, stumps, count, dense, fire, out);
}

void accumulate_two(double bias0, const int32_t* stumps0, int64_t count0, double bias1,
                    const int32_t* stumps1, int64_t count1, const Model::DenseStump* dense,
                    const uint32_t* fire, double* out0, double* out1) {
#if defined(__x86_64__)
  if (kHasAvx512) {
    return accumulate_two_avx512(bias0, stumps0, count0, bias1, stumps1, count1, dense, fire,
                                 out0, out1);
  }
#endif
  accumulate_lanes_clones(bias0, stumps0, count0, dense, fire, out0);
  accumulate_lanes_clones(bias1, stumps1, count1, dense, fire, out1);
}

}  // namespace detail

namespace {

// Whether any of the kBatch lanes passes offer()'s tests with the cutoff one relaxed to >= (as
// score_batch's scalar loop): most classes pass in no lane. Lanes past the batch's count may
// pass spuriously; the scalar loop skips them.
LMB_CLONES_AVX2 bool any_lane_passes(const double* score, const double* background,
                                     const double* cutoff, double min_margin, double min_score) {
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
inline bool better(double s, int32_t c, double ts, int32_t tc) {
  return s > ts || (s == ts && c < tc);
}

}  // namespace

void Classifier::offer(int32_t j, int32_t cls, double score, double bg) {
  if (!(score - bg > options_.min_margin && score >= options_.min_score)) return;
  std::vector<Candidate>& lane = lanes_[j];
  const size_t k = static_cast<size_t>(options_.top_k);
  if (lane.size() >= k && !better(score, cls, cutoff_[j].score, cutoff_[j].cls)) return;
  lane.push_back({score, cls});
  if (lane.size() >= 2 * k + 64) {  // keep the best k; later offers must beat the k-th
    const auto by_rank = [](const Candidate& x, const Candidate& y) {
      return better(x.score, x.cls, y.score, y.cls);
    };
    std::nth_element(lane.begin(), lane.begin() + static_cast<std::ptrdiff_t>(k - 1), lane.end(), by_rank);
    cutoff_[j] = lane[k - 1];
    cutoff_score_[j] = cutoff_[j].score;
    lane.resize(k);
  }
}

void Classifier::score_batch(const int32_t* ids, int32_t count, const int32_t* classes, int32_t num,
                             const int32_t* lists) {
  const Model& m = *model_;
  // Fire masks of every stump (stale value rows of lanes >= count, or of dims the word does not
  // need, give bits no scored class reads).
  const std::vector<Model::DenseStump>& stumps = m.dense_stumps();
  detail::fire_masks(stumps.data(), stumps.size(), values_.data(), fire_.data());
  const std::vector<double>& bias = m.data().bias;
  const int64_t* begin = m.class_stump_begin().data();
  const int32_t* index = m.class_stump_index().data();
  const int32_t C = m.num_classes();
  detail::accumulate_lanes(bias[C], index + begin[C], begin[C + 1] - begin[C], stumps.data(),
                           fire_.data(), background_.data());
  for (int32_t j = 0; j < count; ++j) {
    lanes_[j].clear();
    cutoff_[j] = {-std::numeric_limits<double>::infinity(), std::numeric_limits<int32_t>::max()};
    cutoff_score_[j] = cutoff_[j].score;
  }
  // Two classes at a time (two independent chains of additions), offered in class order. Their
  // stump lists follow each other in `lists`.
  for (int32_t i = 0; i < num; i += 2) {
    const int32_t c0 = classes[i], c1 = i + 1 < num ? classes[i + 1] : -1;
    const int64_t n0 = begin[c0 + 1] - begin[c0];
    if (c1 >= 0) {
      const int64_t n1 = begin[c1 + 1] - begin[c1];
      detail::accumulate_two(bias[c0], lists, n0, bias[c1], lists + n0, n1, stumps.data(),
                             fire_.data(), class_out_.data(), class_out_.data() + kBatch);
      lists += n0 + n1;
    } else {
      detail::accumulate_lanes(bias[c0], lists, n0, stumps.data(), fire_.data(),
                               class_out_.data());
      lists += n0;
    }
    for (int32_t h = 0; h < (c1 >= 0 ? 2 : 1); ++h) {
      const int32_t c = h == 0 ? c0 : c1;
      const double* out = class_out_.data() + h * kBatch;
      if (!any_lane_passes(out, background_.data(), cutoff_score_.data(), options_.min_margin,
                           options_.min_score)) {
        continue;
      }
      for (int32_t j = 0; j < count; ++j) {
        // offer()'s tests, the cutoff one relaxed to >= (inline: most classes fail here).
        const double s = out[j];
        if (s - background_[j] > options_.min_margin && s >= options_.min_score && s >= cutoff_[j].score) {
          offer(j, c, s, background_[j]);
        }
      }
    }
  }
  const auto by_rank = [](const Candidate& x, const Candidate& y) {
    return better(x.score, x.cls, y.score, y.cls);
  };
  for (int32_t j = 0; j < count; ++j) {
    std::vector<Candidate>& lane = lanes_[j];
    const size_t keep = std::min(lane.size(), static_cast<size_t>(options_.top_k));
    std::partial_sort(lane.begin(), lane.begin() + static_cast<std::ptrdiff_t>(keep), lane.end(), by_rank);
    for (size_t i = 0; i < keep; ++i) {
      ClassMatch match;
      match.cls = lane[i].cls;
      match.landmark = m.class_landmark(match.cls);
      match.score = lane[i].score;
      match.background_score = background_[j];
      pending_.emplace_back(ids[j], match);
    }
  }
}

KeypointMatches Classifier::classify(const FrameKeypoints& frame, const uint8_t* descriptors,
                                     const std::string& where, double* embedding_ms) {
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
  pending_.clear();
  for (int32_t g = 0; g < groups; ++g) {
    const int32_t* classes = all_classes_.data();
    int32_t num = m.num_classes();
    const int32_t* lists = m.class_stump_index().data();  // classes 0..C-1 are consecutive
    if (inverted) {
      classes = m.word_classes().data() + m.word_class_begin()[g];
      num = m.word_class_begin()[g + 1] - m.word_class_begin()[g];
      lists = m.word_stream().data() + m.word_stream_begin()[g];
    }
    for (int32_t b = word_begin_[g]; b < word_begin_[g + 1]; b += kBatch) {
      const int32_t count = std::min(kBatch, word_begin_[g + 1] - b);
      if (embedding_ms) t0 = Clock::now();
      for (int32_t j = 0; j < count; ++j) {
        const int32_t k = order_[b + j];
        const uint8_t* desc = descriptors + static_cast<int64_t>(k) * bytes;
        uint8_t* lane = values_.data() + j;  // dim-major: value of used dim u at lane[u * kBatch]
        if (!inverted) {
          compute_used_values(k, desc, word_values_.data());
          for (size_t u = 0; u < U; ++u) lane[u * kBatch] = word_values_[u];
          continue;
        }
        // Only the dims this word's candidates and the background read.
        context_.compute_dims(k, m.word_plan(g), desc, word_values_.data());
        const int32_t u0 = m.word_used_begin()[g], u1 = m.word_used_begin()[g + 1];
        const int32_t* used = m.word_used().data() + u0;
        for (int32_t i = 0; i < u1 - u0; ++i) lane[used[i] * kBatch] = word_values_[i];
      }
      if (embedding_ms) embedding += Clock::now() - t0;
      score_batch(order_.data() + b, count, classes, num, lists);
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
