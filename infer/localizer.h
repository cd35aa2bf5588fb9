// Frame -> ranked 2D-3D matches -> 6-DoF pose, the inference library's main entry point.
//
//   Localizer localizer(Model::load("model.lbm"));
//   LocalizeResult r = localizer.localize(camera, keypoints, descriptors, gravity_in_cam);
//   if (r.localized) use(r.pose.cam_from_world);   // r.confidence: P(pose right)
//
// Steps: quantize each descriptor to its visual word, place the keypoints in the gravity-aligned
// normalized plane (common/context_embedding.h), classify them (infer/classifier.h), then feed the
// matches to estimate_absolute_pose (infer/pose_estimator.h): each keypoint's best match, or its
// pose_top_k best, keypoint pixel <-> the class's 3D landmark, with the match's margin over the
// background (score - background score) as the PROSAC order.
//
// Inputs: keypoints in pixels of the distorted image with COLMAP's convention (centre of the
// top-left pixel at (0.5, 0.5); add 0.5 to an OpenCV KeyPoint::pt), scale = detector diameter in pixels
// (lmb::Keypoint); descriptors: keypoints.size() rows of model.descriptor_bytes() bytes; gravity_in_cam: the direction
// of gravity (down) in the camera frame (x right, y down, z forward), any non-zero length.
//
// Confidence: the pose's evidence (infer/pose_confidence.h) and, when the model holds a pose
// calibration (Model::calibrated(), fitted by `lboost export`), the probability that the pose is
// within 20 cm / 5 deg of the truth. `localized` is the answer to act on: the estimator found a
// pose (pose.success: at least min_inliers inliers) and, with a calibrated model, its probability
// reaches the model's operating point (or options.min_confidence). With an uncalibrated model
// (files before version 3) `localized` is pose.success, confidence is -1 and calibrated false.
//
// Errors: invalid input (null descriptors, invalid camera, non-finite or non-positive keypoint
// sizes, zero gravity) throws lmb::Error. Failing to localize is not an error: pose.success false.
//
// Threading: localize() is const and keeps its buffers per call, so one Localizer (and one Model)
// may serve any number of threads at once; results depend only on the inputs and options.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/types.h"
#include "infer/classifier_options.h"
#include "infer/export.h"
#include "infer/model.h"
#include "infer/pose_confidence.h"
#include "infer/pose_estimator.h"

namespace lmb {

struct LMB_INFER_EXPORT LocalizerOptions {
  ClassifierOptions classifier;  // top_k, inverted file, background margin, min score
  // Matches per keypoint fed to the pose estimator (1..classifier.top_k): 1 = the best match only.
  int pose_top_k = 1;
  // At most this many correspondences, those with the largest margin over the background
  // (score - background score; ties: keypoint order); 0 = all.
  int max_correspondences = 0;
  PoseEstimatorOptions pose;  // RANSAC samples, inlier threshold (px), seed, PROSAC, refinement
  // The probability a calibrated model's pose must reach to count as localized, in [0, 1];
  // negative = the model's own operating point (PoseCalibration::threshold). Ignored by an
  // uncalibrated model.
  double min_confidence = -1.0;

  // Throws lmb::Error naming the field.
  void check() const;
};

// Milliseconds spent in each step of one localize() call (steady clock).
struct LocalizeTimings {
  double words_ms = 0.0;           // descriptor quantization
  double embedding_ms = 0.0;       // frame index + context dims (inside classification)
  double classification_ms = 0.0;  // scoring and ranking (embedding excluded)
  double pose_ms = 0.0;
  double total_ms = 0.0;
};

struct LocalizeResult {
  KeypointMatches matches;  // ranked matches of every keypoint
  PoseResult pose;          // cam_from_world, inlier mask of correspondences, RANSAC stats
  // One entry per correspondence given to the pose estimator (pose.inlier_mask is aligned):
  std::vector<int32_t> correspondence_keypoint;  // keypoint index
  std::vector<int32_t> correspondence_match;     // index into matches.matches
  PoseEvidence evidence;                         // what the pose's confidence is computed from
  bool calibrated = false;                       // the model has a pose calibration
  double confidence = -1.0;                      // P(pose right) in [0, 1) when calibrated (0 without a pose), else -1
  double confidence_threshold = -1.0;            // the operating point applied when calibrated, else -1
  bool localized = false;                        // pose.success and (uncalibrated or confidence >= threshold)
  LocalizeTimings timings;
};

// The work of a frame that does not depend on the model, done once for every model of one
// vocabulary (an AreaBundle's areas): the descriptors' visual words, the keypoints placed in the
// gravity-aligned normalized plane, and the frame's context index (common/context_embedding.h).
// Localizer::localize(camera, keypoints, descriptors, prepared, options) with it gives the matches
// and pose that localize() computes from scratch. Read-only once built: any number of threads may
// use one at once.
class LMB_INFER_EXPORT PreparedFrame {
 public:
  // `model`: its vocabulary quantizes the descriptors (keypoints.size() rows of its
  // descriptor_bytes()). Throws lmb::Error as localize() does for invalid input.
  PreparedFrame(std::shared_ptr<const Model> model, const Camera& camera, const std::vector<Keypoint>& keypoints,
                const uint8_t* descriptors, const Eigen::Vector3d& gravity_in_cam);
  ~PreparedFrame();
  PreparedFrame(const PreparedFrame&) = delete;
  PreparedFrame& operator=(const PreparedFrame&) = delete;

  // `model` reads this frame as its own: the same vocabulary and context region count.
  bool serves(const Model& model) const;
  int32_t size() const;
  double words_ms() const { return words_ms_; }          // quantization
  double embedding_ms() const { return embedding_ms_; }  // keypoint placement + context index

 private:
  friend class Localizer;
  struct Frame;                         // the placed keypoints and their context index (infer/localizer.cc)
  std::shared_ptr<const Model> model_;  // the vocabulary, and the regions the index refers to
  std::unique_ptr<Frame> frame_;
  double words_ms_ = 0.0;
  double embedding_ms_ = 0.0;
};

class LMB_INFER_EXPORT Localizer {
 public:
  // Throws lmb::Error for a null model or invalid options.
  explicit Localizer(std::shared_ptr<const Model> model, const LocalizerOptions& options = {});

  LocalizeResult localize(const Camera& camera, const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                          const Eigen::Vector3d& gravity_in_cam) const;
  // The same with explicit options (per-call settings; options.check() first).
  LocalizeResult localize(const Camera& camera, const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                          const Eigen::Vector3d& gravity_in_cam, const LocalizerOptions& options) const;
  // The same with the frame's model-independent work done (`prepared` of the same keypoints,
  // descriptors, camera and gravity; it must serve this model): the same result. Its timings count
  // only this call's work (words_ms 0; embedding_ms the context dims only). Throws lmb::Error when
  // `prepared` does not serve the model or holds another keypoint count.
  LocalizeResult localize(const Camera& camera, const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                          const PreparedFrame& prepared, const LocalizerOptions& options) const;

  const Model& model() const { return *model_; }
  const std::shared_ptr<const Model>& shared_model() const { return model_; }
  const LocalizerOptions& options() const { return options_; }

 private:
  std::shared_ptr<const Model> model_;
  LocalizerOptions options_;
};

}  // namespace lmb
