#include "infer/classifier.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

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
  stump_out_.resize(model_->dense_stumps().size() * kBatch);
  class_out_.resize(kBatch);
  background_.resize(kBatch);
  all_classes_.resize(static_cast<size_t>(model_->num_classes()));
  for (int32_t c = 0; c < model_->num_classes(); ++c) all_classes_[c] = c;
  lanes_.resize(kBatch);
  cutoff_.resize(kBatch);
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

// 4 lanes (one AVX2 register, two SSE2 ones), unaligned loads. (8 lanes with an AVX-512 clone
// measured no faster on this machine's EPYC.)
using Batch = double __attribute__((vector_size(32), aligned(8)));
constexpr int32_t kLanes = 4;
constexpr int32_t kVectors = Classifier::kBatch / kLanes;

// out[j] = bias + the stump outputs of `stumps` (training order) in lane j, for kBatch lanes:
// lane by lane the same additions in the same order as BoostModel::scores. Cloned for AVX2 (picked
// at load time) and the baseline ISA; IEEE additions give the same doubles in both.
// Under ThreadSanitizer the clone resolver (an IFUNC the dynamic loader runs before the TSan
// runtime starts) is instrumented and crashes every program at load: TSan builds
// (scripts/tsan.sh) take the baseline code only.
#if defined(__SANITIZE_THREAD__)
#define LMB_CLONES_AVX2
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define LMB_CLONES_AVX2
#endif
#endif
#ifndef LMB_CLONES_AVX2
#define LMB_CLONES_AVX2 __attribute__((target_clones("avx2", "default")))
#endif

LMB_CLONES_AVX2 void accumulate_lanes(
    double bias, const int32_t* stumps, int64_t count, const double* stump_out, double* out) {
  Batch acc[kVectors];
  for (int32_t v = 0; v < kVectors; ++v) acc[v] = Batch{bias, bias, bias, bias};
  for (int64_t e = 0; e < count; ++e) {
    const Batch* h = reinterpret_cast<const Batch*>(stump_out + static_cast<int64_t>(stumps[e]) *
                                                                    Classifier::kBatch);
    for (int32_t v = 0; v < kVectors; ++v) acc[v] += h[v];
  }
  for (int32_t v = 0; v < kVectors; ++v) std::memcpy(out + kLanes * v, &acc[v], sizeof(Batch));
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
    lane.resize(k);
  }
}

void Classifier::score_batch(const int32_t* ids, int32_t count, const int32_t* classes, int32_t num) {
  const Model& m = *model_;
  const size_t U = m.used_dims().size();
  // Stump outputs of every stump (stale value rows of lanes >= count, or of dims the word does
  // not need, give outputs no scored class reads).
  const std::vector<Model::DenseStump>& stumps = m.dense_stumps();
  for (size_t s = 0; s < stumps.size(); ++s) {
    const Model::DenseStump& st = stumps[s];
    double* out = stump_out_.data() + s * kBatch;
    const uint8_t* v = values_.data() + st.used;
    for (int32_t j = 0; j < kBatch; ++j) out[j] = v[j * U] > st.theta ? st.above : st.below;
  }
  const std::vector<double>& bias = m.data().bias;
  const int64_t* begin = m.class_stump_begin().data();
  const int32_t* index = m.class_stump_index().data();
  const int32_t C = m.num_classes();
  accumulate_lanes(bias[C], index + begin[C], begin[C + 1] - begin[C], stump_out_.data(),
                   background_.data());
  for (int32_t j = 0; j < count; ++j) {
    lanes_[j].clear();
    cutoff_[j] = {-std::numeric_limits<double>::infinity(), std::numeric_limits<int32_t>::max()};
  }
  for (int32_t i = 0; i < num; ++i) {
    const int32_t c = classes[i];
    accumulate_lanes(bias[c], index + begin[c], begin[c + 1] - begin[c], stump_out_.data(),
                     class_out_.data());
    for (int32_t j = 0; j < count; ++j) {
      // offer()'s tests, the cutoff one relaxed to >= (inline: most classes fail here).
      const double s = class_out_[j];
      if (s - background_[j] > options_.min_margin && s >= options_.min_score && s >= cutoff_[j].score) {
        offer(j, c, s, background_[j]);
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
    if (inverted) {
      classes = m.word_classes().data() + m.word_class_begin()[g];
      num = m.word_class_begin()[g + 1] - m.word_class_begin()[g];
    }
    for (int32_t b = word_begin_[g]; b < word_begin_[g + 1]; b += kBatch) {
      const int32_t count = std::min(kBatch, word_begin_[g + 1] - b);
      if (embedding_ms) t0 = Clock::now();
      for (int32_t j = 0; j < count; ++j) {
        const int32_t k = order_[b + j];
        const uint8_t* desc = descriptors + static_cast<int64_t>(k) * bytes;
        uint8_t* row = values_.data() + j * U;
        if (!inverted) {
          compute_used_values(k, desc, row);
          continue;
        }
        // Only the dims this word's candidates and the background read.
        context_.compute_dims(k, m.word_plan(g), desc, word_values_.data());
        const int32_t u0 = m.word_used_begin()[g], u1 = m.word_used_begin()[g + 1];
        const int32_t* used = m.word_used().data() + u0;
        for (int32_t i = 0; i < u1 - u0; ++i) row[used[i]] = word_values_[i];
      }
      if (embedding_ms) embedding += Clock::now() - t0;
      score_batch(order_.data() + b, count, classes, num);
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
