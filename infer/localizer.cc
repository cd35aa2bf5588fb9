#include "infer/localizer.h"

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>

#include "common/context_embedding.h"
#include "common/error.h"
#include "infer/classifier.h"

namespace lmb {

void LocalizerOptions::check() const {
  classifier.check();
  LMB_CHECK(max_correspondences >= 0,
            "localizer options: max_correspondences = " << max_correspondences << " must be >= 0");
  LMB_CHECK(pose_top_k >= 1 && pose_top_k <= classifier.top_k,
            "localizer options: pose_top_k = " << pose_top_k << " must be in 1..classifier.top_k (" << classifier.top_k
                                               << ")");
  pose.check();
  LMB_CHECK(!std::isnan(min_confidence) && min_confidence <= 1.0,
            "localizer options: min_confidence = " << min_confidence << " must be <= 1 (negative: the model's)");
}

Localizer::Localizer(std::shared_ptr<const Model> model, const LocalizerOptions& options)
    : model_(std::move(model)), options_(options) {
  LMB_CHECK(model_ != nullptr, "localizer: null model");
  options_.check();
}

LocalizeResult Localizer::localize(const Camera& camera, const std::vector<Keypoint>& keypoints,
                                   const uint8_t* descriptors, const Eigen::Vector3d& gravity_in_cam) const {
  return localize(camera, keypoints, descriptors, gravity_in_cam, options_);
}

namespace {
using Clock = std::chrono::steady_clock;
double elapsed_ms(Clock::time_point from, Clock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}
}  // namespace

struct PreparedFrame::Frame {
  explicit Frame(const Model& model) : context(model.regions(), model.num_words()) {}
  FrameKeypoints keypoints;
  FrameContext context;
};

PreparedFrame::PreparedFrame(std::shared_ptr<const Model> model, const Camera& camera,
                             const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                             const Eigen::Vector3d& gravity_in_cam)
    : model_(std::move(model)) {
  LMB_CHECK(model_ != nullptr, "prepared frame: null model");
  frame_ = std::make_unique<Frame>(*model_);
  camera.check("localize: camera");
  const int64_t n64 = static_cast<int64_t>(keypoints.size());
  LMB_CHECK(n64 <= INT32_MAX, "localize: " << n64 << " keypoints are too many");
  const int32_t n = static_cast<int32_t>(n64);
  LMB_CHECK(n == 0 || descriptors != nullptr, "localize: null descriptors for " << n << " keypoints");
  const Clock::time_point t_start = Clock::now();
  std::vector<uint8_t> words(static_cast<size_t>(n));
  if (n > 0) model_->vocabulary().quantize(descriptors, n, words.data());
  const Clock::time_point t_words = Clock::now();
  frame_->keypoints =
      frame_keypoints_from_detections(camera, keypoints.data(), words.data(), n, gravity_in_cam, "localize");
  frame_->context.reset(frame_->keypoints, "localize");
  words_ms_ = elapsed_ms(t_start, t_words);
  embedding_ms_ = elapsed_ms(t_words, Clock::now());
}

PreparedFrame::~PreparedFrame() = default;

int32_t PreparedFrame::size() const { return frame_->keypoints.size(); }

bool PreparedFrame::serves(const Model& model) const {
  return &model == model_.get() ||
         (model.vocabulary() == model_->vocabulary() && model.regions().size() == model_->regions().size());
}

LocalizeResult Localizer::localize(const Camera& camera, const std::vector<Keypoint>& keypoints,
                                   const uint8_t* descriptors, const Eigen::Vector3d& gravity_in_cam,
                                   const LocalizerOptions& options) const {
  options.check();
  const Clock::time_point t_start = Clock::now();
  const PreparedFrame prepared(model_, camera, keypoints, descriptors, gravity_in_cam);
  LocalizeResult result = localize(camera, keypoints, descriptors, prepared, options);
  result.timings.words_ms = prepared.words_ms();
  result.timings.embedding_ms += prepared.embedding_ms();
  result.timings.total_ms = elapsed_ms(t_start, Clock::now());
  return result;
}

LocalizeResult Localizer::localize(const Camera& camera, const std::vector<Keypoint>& keypoints,
                                   const uint8_t* descriptors, const PreparedFrame& prepared,
                                   const LocalizerOptions& options) const {
  options.check();
  const Model& m = *model_;
  LMB_CHECK(prepared.serves(m), "localize: the prepared frame was made with another vocabulary or region count");
  const int32_t n = prepared.size();
  LMB_CHECK(static_cast<size_t>(n) == keypoints.size(),
            "localize: the prepared frame has " << n << " keypoints, the call " << keypoints.size());
  LocalizeResult result;
  const Clock::time_point t_start = Clock::now();
  Classifier classifier(model_, options.classifier);
  const Clock::time_point t_frame = Clock::now();
  double embedding_ms = 0.0;
  result.matches =
      classifier.classify(prepared.frame_->keypoints, prepared.frame_->context, descriptors, "localize", &embedding_ms);
  const Clock::time_point t_classified = Clock::now();
  // Embedding: the context dims' values (the prepared frame holds the rest).
  result.timings.embedding_ms = embedding_ms;
  result.timings.classification_ms = elapsed_ms(t_frame, t_classified) - embedding_ms;

  for (int32_t k = 0; k < n; ++k) {
    const int32_t count = std::min(result.matches.count(k), options.pose_top_k);
    for (int32_t j = 0; j < count; ++j) {
      result.correspondence_keypoint.push_back(k);
      result.correspondence_match.push_back(result.matches.begin[k] + j);
    }
  }
  const size_t limit = static_cast<size_t>(options.max_correspondences);
  if (limit > 0 && result.correspondence_match.size() > limit) {
    std::vector<size_t> order(result.correspondence_match.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    const auto margin = [&](size_t i) {
      const ClassMatch& c = result.matches.matches[result.correspondence_match[i]];
      return c.score - c.background_score;
    };
    std::stable_sort(order.begin(), order.end(), [&](size_t x, size_t y) { return margin(x) > margin(y); });
    order.resize(limit);
    std::sort(order.begin(), order.end());  // back to keypoint order
    std::vector<int32_t> keypoint, match;
    for (size_t i : order) {
      keypoint.push_back(result.correspondence_keypoint[i]);
      match.push_back(result.correspondence_match[i]);
    }
    result.correspondence_keypoint = std::move(keypoint);
    result.correspondence_match = std::move(match);
  }
  // PROSAC samples the correspondences in the order of their margin over the background.
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  std::vector<double> margins;
  for (size_t i = 0; i < result.correspondence_keypoint.size(); ++i) {
    const int32_t k = result.correspondence_keypoint[i];
    const ClassMatch& c = result.matches.matches[result.correspondence_match[i]];
    pixels.emplace_back(keypoints[k].x, keypoints[k].y);
    points.push_back(m.class_position(c.cls));
    margins.push_back(c.score - c.background_score);
  }
  result.pose = estimate_absolute_pose(camera, pixels, points, options.pose, margins);
  result.evidence = pose_evidence(camera, pixels, margins, result.pose, n);
  result.localized = result.pose.success;
  if (m.calibrated()) {
    result.calibrated = true;
    result.confidence = m.calibration().probability(result.evidence);
    result.confidence_threshold = options.min_confidence >= 0.0 ? options.min_confidence : m.calibration().threshold;
    result.localized = result.pose.success && result.confidence >= result.confidence_threshold;
  }
  const Clock::time_point t_end = Clock::now();
  result.timings.pose_ms = elapsed_ms(t_classified, t_end);
  result.timings.total_ms = elapsed_ms(t_start, t_end);
  return result;
}

}  // namespace lmb
