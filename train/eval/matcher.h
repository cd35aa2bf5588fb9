// The matcher interface of `lboost eval`: a query frame's keypoints -> per keypoint, the ranked
// landmarks with scores, and the 2D-3D matches the method would give to the pose estimator.
// LandmarkBoost (dense and inverted file, train/eval/landmarkboost_matcher.h) and every descriptor
// baseline (train/eval/descriptor_matchers.h) implement it; the evaluation pipeline
// (train/eval/eval_pipeline.h) runs them all the same way: match every query frame, then the same
// pose stage (train/eval/pose_stage.h) and the same metrics.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "common/camera.h"
#include "common/rigid3.h"
#include "common/types.h"
#include "train/eval/metrics.h"

namespace lmb {

// One query frame as the matchers and the pose stage see it. The descriptors point into the map
// the frame comes from (keypoints.size() rows of the map's descriptor_bytes bytes).
struct EvalQuery {
  frame_t frame = kInvalidFrameId;  // index in the map
  const Camera* camera = nullptr;
  std::vector<Keypoint> keypoints;  // pixels of the distorted image (COLMAP convention)
  const uint8_t* descriptors = nullptr;
  Eigen::Vector3d gravity_in_cam = Eigen::Vector3d(0, 1, 0);
  Rigid3d true_cam_from_world;  // ground truth
  // Per keypoint: its true landmark when that landmark is one of the model's classes, else
  // kInvalidLandmarkId (a "background" keypoint for the metrics).
  std::vector<landmark_t> truth;
};

// One 2D-3D match a method gives to the pose estimator.
struct Correspondence {
  int32_t keypoint = -1;  // index into EvalQuery::keypoints
  landmark_t landmark = kInvalidLandmarkId;
  Eigen::Vector3d point_world = Eigen::Vector3d::Zero();  // the landmark's position, map units
  // Higher = more trusted (LandmarkBoost: the margin over the background; descriptors: minus the
  // distance); orders the matches for --max-correspondences.
  double confidence = 0.0;
};

// What a method returns for one frame.
struct FrameMatches {
  // Per keypoint: up to top_k distinct landmarks, best first, WITHOUT rejection (the ranking that
  // precision@1, MRR and the miss rate read). Scores: higher is better.
  std::vector<std::vector<RankedCandidate>> ranking;
  // The accepted matches, at most one a keypoint, in keypoint order: what the method's own
  // rejection (LandmarkBoost's background margin, a ratio test) keeps. A keypoint without one was
  // rejected. The pose stage caps them at --max-correspondences by confidence.
  std::vector<Correspondence> accepted;
  double match_ms = 0.0;  // wall time of the timed matching, milliseconds
  double cpu_ms = 0.0;    // the calling thread's CPU time of the same, milliseconds
};

// A method of `lboost eval`. match() is called once per query frame, one frame at a time, on one
// thread; it times its own work (the part an application would run: for LandmarkBoost the
// configured classification, for a baseline its k-NN search and test).
class Matcher {
 public:
  virtual ~Matcher() = default;
  virtual FrameMatches match(const EvalQuery& query) const = 0;
  // The accepted matches of `query` as if the landmarks for which excluded(landmark) is true were
  // not in the map: per keypoint, its best remaining landmark under the method's own rejection
  // (LandmarkBoost: the best class not excluded beating the background by min_margin; a
  // descriptor baseline: the nearest observation of a landmark not excluded, and its ratio test
  // among those). Untimed. The pose calibration's "elsewhere" frames
  // (train/eval/pose_calibration_fit.h) use it.
  virtual std::vector<Correspondence> accepted_without(const EvalQuery& query,
                                                       const std::function<bool(landmark_t)>& excluded) const = 0;
  // The method's own parameters for the report (e.g. the ratio, the ANN index's parameters).
  virtual nlohmann::json parameters() const { return nlohmann::json::object(); }
};

}  // namespace lmb
