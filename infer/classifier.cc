#include "infer/classifier.h"

#include <algorithm>
#include <chrono>
#include <cmath>

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
  values_.resize(model_->used_dims().size());
  word_values_.resize(model_->used_dims().size());
  scores_.resize(static_cast<size_t>(model_->num_classes()) + 1);
  all_classes_.resize(static_cast<size_t>(model_->num_classes()));
  for (int32_t c = 0; c < model_->num_classes(); ++c) all_classes_[c] = c;
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

void Classifier::rank(const int32_t* classes, const double* scores, int32_t num, double background,
                      KeypointMatches* out) {
  order_.clear();
  for (int32_t i = 0; i < num; ++i) {
    const double s = scores[i];
    if (s - background > options_.min_margin && s >= options_.min_score) order_.push_back(i);
  }
  const auto better = [&](int32_t x, int32_t y) {
    return scores[x] > scores[y] || (scores[x] == scores[y] && classes[x] < classes[y]);
  };
  const size_t keep = std::min(order_.size(), static_cast<size_t>(options_.top_k));
  std::partial_sort(order_.begin(), order_.begin() + static_cast<std::ptrdiff_t>(keep), order_.end(),
                    better);
  for (size_t i = 0; i < keep; ++i) {
    ClassMatch match;
    match.cls = classes[order_[i]];
    match.landmark = model_->class_landmark(match.cls);
    match.score = scores[order_[i]];
    match.background_score = background;
    out->matches.push_back(match);
  }
  out->begin.push_back(static_cast<int32_t>(out->matches.size()));
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
  KeypointMatches out;
  out.begin.reserve(static_cast<size_t>(n) + 1);
  out.begin.push_back(0);
  const int32_t C = m.num_classes();
  const int32_t bytes = m.descriptor_bytes();
  for (int32_t k = 0; k < n; ++k) {
    const uint8_t* desc = descriptors + static_cast<int64_t>(k) * bytes;
    if (embedding_ms) t0 = Clock::now();
    if (!options_.use_inverted_file) {
      compute_used_values(k, desc, values_.data());
      if (embedding_ms) embedding += Clock::now() - t0;
      dense_scores(values_.data(), scores_.data());
      rank(all_classes_.data(), scores_.data(), C, scores_[C], &out);
      continue;
    }
    const int32_t w = frame.word[k];
    // Only the dims this word's candidates and the background read.
    const int32_t u0 = m.word_used_begin()[w], u1 = m.word_used_begin()[w + 1];
    context_.compute_dims(k, m.word_plan(w), desc, word_values_.data());
    const int32_t* used = m.word_used().data() + u0;
    for (int32_t i = 0; i < u1 - u0; ++i) values_[used[i]] = word_values_[i];
    if (embedding_ms) embedding += Clock::now() - t0;
    const int32_t c0 = m.word_class_begin()[w], c1 = m.word_class_begin()[w + 1];
    const int32_t* candidates = m.word_classes().data() + c0;
    for (int32_t i = 0; i < c1 - c0; ++i) scores_[i] = class_score(values_.data(), candidates[i]);
    const double background = class_score(values_.data(), C);
    rank(candidates, scores_.data(), c1 - c0, background, &out);
  }
  if (embedding_ms) *embedding_ms = std::chrono::duration<double, std::milli>(embedding).count();
  return out;
}

}  // namespace lmb
