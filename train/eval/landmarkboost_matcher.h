// LandmarkBoost as a matcher of `lboost eval` (train/eval/matcher.h): the inference library's
// classification of a frame, as the Localizer runs it (infer/localizer.h: quantize the descriptors,
// place the keypoints, Classifier::classify), dense or with the inverted file.
//
// Two passes a frame:
//   - the ranking: every keypoint's top_k landmark classes WITHOUT background rejection
//     (min_margin -inf), each scored by its margin over the background (the same order as the
//     class scores within a keypoint, and comparable across keypoints); not timed;
//   - the configured classification (background rejection at min_margin), timed: its best match
//     per keypoint is the accepted match, confidence = its margin, point = the class's position in
//     the model. With pose_top_k = 1 these are exactly the Localizer's correspondences.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "common/landmark_map.h"

#include "infer/classifier.h"
#include "infer/model.h"
#include "train/eval/matcher.h"

namespace lmb {

class LandmarkBoostMatcher : public Matcher {
 public:
  // options: top_k, use_inverted_file, min_margin, min_score, screening. rank false: no ranking
  // pass (FrameMatches::ranking holds empty lists; the pose calibration needs the accepted matches
  // only). Throws lmb::Error on a null model or invalid options.
  LandmarkBoostMatcher(std::shared_ptr<const Model> model, const ClassifierOptions& options, bool rank = true);

  FrameMatches match(const EvalQuery& query) const override;
  std::vector<Correspondence> accepted_without(const EvalQuery& query,
                                               const std::function<bool(landmark_t)>& excluded) const override;
  nlohmann::json parameters() const override;

 private:
  KeypointMatches classify(const EvalQuery& query, const ClassifierOptions& options) const;

  std::shared_ptr<const Model> model_;
  ClassifierOptions options_;  // the configured classification
  ClassifierOptions ranking_;  // the same without rejection
  bool rank_ = true;
};

// `model` with the descriptor fusion's exemplars of the map keypoints `excluded` (sorted) removed:
// the model LandmarkBoost ranks held-out map observations with, so that, like the descriptor
// baselines' index, the fusion does not find a held-out keypoint's own descriptor (at distance 0).
// The model itself when it has no fusion or nothing is excluded. The exemplars must be the ones
// export stores for this map (exemplar_keypoints, train/export/descriptor_fusion.h, or a subset of
// them in the same order, export --max-exemplars). Throws lmb::Error when they are not, or when a
// class would keep no exemplar; with keep_sole, such a class keeps its exemplars instead (the pose
// calibration's frames: a landmark seen only in them).
std::shared_ptr<const Model> without_exemplars(const std::shared_ptr<const Model>& model, const LandmarkMap& map,
                                               const std::vector<int64_t>& excluded, bool keep_sole = false);

}  // namespace lmb
