#include "train/eval/landmarkboost_matcher.h"

#include <limits>
#include <utility>

#include "common/context_embedding.h"
#include "common/error.h"
#include "train/eval/report.h"
#include "train/eval/timing.h"

namespace lmb {

LandmarkBoostMatcher::LandmarkBoostMatcher(std::shared_ptr<const Model> model, const ClassifierOptions& options,
                                           bool rank)
    : model_(std::move(model)), options_(options), ranking_(options), rank_(rank) {
  LMB_CHECK(model_ != nullptr, "LandmarkBoostMatcher: null model");
  options_.check();
  ranking_.min_margin = -std::numeric_limits<double>::infinity();
}

// The Localizer's classification steps (infer/localizer.cc), without the pose.
KeypointMatches LandmarkBoostMatcher::classify(const EvalQuery& q, const ClassifierOptions& options) const {
  const int32_t n = static_cast<int32_t>(q.keypoints.size());
  std::vector<uint8_t> words(static_cast<size_t>(n));
  if (n > 0) model_->vocabulary().quantize(q.descriptors, n, words.data());
  const FrameKeypoints frame =
      frame_keypoints_from_detections(*q.camera, q.keypoints.data(), words.data(), n, q.gravity_in_cam, "localize");
  Classifier classifier(model_, options);
  return classifier.classify(frame, q.descriptors, "localize");
}

FrameMatches LandmarkBoostMatcher::match(const EvalQuery& q) const {
  LMB_CHECK(q.camera != nullptr, "LandmarkBoostMatcher: query frame " << q.frame << " has no camera");
  FrameMatches r;
  r.ranking.resize(q.keypoints.size());
  const KeypointMatches ranked = rank_ ? classify(q, ranking_) : KeypointMatches();
  for (int32_t k = 0; k < ranked.num_keypoints(); ++k) {
    for (int32_t j = 0; j < ranked.count(k); ++j) {
      const ClassMatch& m = ranked.of(k)[j];
      r.ranking[static_cast<size_t>(k)].push_back(RankedCandidate{m.landmark, m.score - m.background_score});
    }
  }
  const double c0 = thread_cpu_ms();
  const Clock::time_point t0 = Clock::now();
  const KeypointMatches matches = classify(q, options_);
  r.match_ms = ms_since(t0);
  r.cpu_ms = thread_cpu_ms() - c0;
  for (int32_t k = 0; k < matches.num_keypoints(); ++k) {
    if (matches.count(k) == 0) continue;
    const ClassMatch& m = matches.of(k)[0];
    r.accepted.push_back(Correspondence{k, m.landmark, model_->class_position(m.cls), m.score - m.background_score});
  }
  return r;
}

std::vector<Correspondence> LandmarkBoostMatcher::accepted_without(
    const EvalQuery& q, const std::function<bool(landmark_t)>& excluded) const {
  LMB_CHECK(q.camera != nullptr, "LandmarkBoostMatcher: query frame " << q.frame << " has no camera");
  // A class's score and the background's do not depend on the other classes, so the best class
  // left after removing some is the first remaining one of the full ranking under the same
  // rejection.
  ClassifierOptions all = options_;
  all.top_k = model_->num_classes();
  const KeypointMatches matches = classify(q, all);
  std::vector<Correspondence> out;
  for (int32_t k = 0; k < matches.num_keypoints(); ++k) {
    for (int32_t j = 0; j < matches.count(k); ++j) {
      const ClassMatch& m = matches.of(k)[j];
      if (excluded(m.landmark)) continue;
      out.push_back(Correspondence{k, m.landmark, model_->class_position(m.cls), m.score - m.background_score});
      break;
    }
  }
  return out;
}

nlohmann::json LandmarkBoostMatcher::parameters() const {
  return {{"top_k", options_.top_k},
          {"inverted_file", options_.use_inverted_file},
          {"min_margin", json_number_or_string(options_.min_margin)}};
}

}  // namespace lmb
