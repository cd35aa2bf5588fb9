#include "train/eval/landmarkboost_matcher.h"

#include <algorithm>
#include <cstring>
#include <limits>
#include <utility>

#include "common/context_embedding.h"
#include "common/error.h"
#include "train/eval/report.h"
#include "train/eval/timing.h"
#include "train/export/descriptor_fusion.h"

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
          {"inverted_file_words", options_.use_inverted_file ? options_.inverted_file_words : 0},
          {"min_margin", json_number_or_string(options_.min_margin)}};
}

std::shared_ptr<const Model> without_exemplars(const std::shared_ptr<const Model>& model, const LandmarkMap& map,
                                               const std::vector<int64_t>& excluded, bool keep_sole) {
  LMB_CHECK(model != nullptr, "eval: no model");
  const ModelData& d = model->data();
  if (!d.fusion.enabled() || excluded.empty()) return model;
  const int32_t C = d.num_classes;
  const int64_t bytes = d.descriptor_bytes;
  LMB_CHECK(map.descriptor_bytes == d.descriptor_bytes,
            "eval: the map's descriptors have " << map.descriptor_bytes << " bytes, the model's " << bytes);
  const std::vector<std::vector<int64_t>> of = exemplar_keypoints(map, d.class_landmark);
  ModelData out = d;
  out.fusion.exemplars.clear();
  out.fusion.exemplar_begin.assign(1, 0);
  for (int32_t c = 0; c < C; ++c) {
    // The class's rows are its map observations, or a subset of them (export --max-exemplars), in
    // keypoint order: each row is matched to the next observation with its descriptor.
    size_t next = 0;
    for (int64_t r = d.fusion.exemplar_begin[c]; r < d.fusion.exemplar_begin[c + 1]; ++r) {
      const uint8_t* row = d.fusion.exemplars.data() + r * bytes;
      while (next < of[c].size() && std::memcmp(row, map.descriptor(of[c][next]), static_cast<size_t>(bytes)) != 0) {
        ++next;
      }
      LMB_CHECK(next < of[c].size(), "eval: descriptor-fusion exemplar "
                                         << r - d.fusion.exemplar_begin[c] << " of class " << c
                                         << " is not a map observation of landmark " << d.class_landmark[c]
                                         << " (a model exported from another map?)");
      const int64_t k = of[c][next++];
      if (std::binary_search(excluded.begin(), excluded.end(), k)) continue;
      out.fusion.exemplars.insert(out.fusion.exemplars.end(), row, row + bytes);
    }
    if (keep_sole && static_cast<int64_t>(out.fusion.exemplars.size()) / bytes == out.fusion.exemplar_begin.back()) {
      out.fusion.exemplars.insert(out.fusion.exemplars.end(),
                                  d.fusion.exemplars.data() + d.fusion.exemplar_begin[c] * bytes,
                                  d.fusion.exemplars.data() + d.fusion.exemplar_begin[c + 1] * bytes);
    }
    const int64_t end = static_cast<int64_t>(out.fusion.exemplars.size()) / bytes;
    LMB_CHECK(end > out.fusion.exemplar_begin.back(), "eval: class "
                                                          << c << " (landmark " << d.class_landmark[c]
                                                          << ") has no map observation outside the held-out ones");
    out.fusion.exemplar_begin.push_back(end);
  }
  return std::make_shared<const Model>(std::move(out));
}

}  // namespace lmb
