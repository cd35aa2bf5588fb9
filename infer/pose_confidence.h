// The parts of a calibrated pose confidence: the probability that an estimated pose is right
// (within 20 cm and 5 degrees of the truth), from what the frame tells, by a logistic model that is
// FITTED on frames with known poses (never hand-tuned), and an operating point chosen for precision.
//
//   PoseEvidence e = pose_evidence(camera, pixels, quality, pose, num_keypoints);
//   double p = calibration.probability(e);             // in (0, 1); 0 without inliers
//   bool trusted = pose.success && p >= calibration.threshold;
//
//   PoseCalibration c = fit_pose_calibration(evidence, right);   // frames with known truth
//   c.threshold = precision_threshold(probabilities, right, 0.95);
//
// The evidence is method-agnostic (no raw classifier scores), so the same features serve
// LandmarkBoost and the descriptor baselines of `lboost eval`:
//   0  log(1 + inliers)
//   1  inlier ratio: inliers / correspondences offered to RANSAC (the usable ones)
//   2  runner-up support: the runner-up pose's inliers / the pose's inliers (infer/ransac.h),
//      capped at 2; high in an aliased place where another pose fits nearly as well
//   3  inlier rank: mean over the inliers of 1 - rank / N, rank 0 = the correspondence the method
//      trusts most (its PROSAC order: LandmarkBoost's margin over the background, a baseline's
//      descriptor distance); 0.5 when there is no order, near 1 when the inliers are the
//      best-ranked matches
//   4  spread: the share of the 4 x 4 grid cells of the image holding an inlier
//   5  offered share: correspondences / keypoints of the frame (1 - the background share when one
//      match per keypoint is offered), capped at 1
//   6  log(1 + correspondences)
// Every feature is 0 for a pose without inliers.
//
// `lboost export` fits a calibration on map frames and stores it in the model file
// (infer/model.h, version 3); the Localizer reports the probability and applies the threshold
// (infer/localizer.h, LocalizeResult::confidence); docs/pose.md, "Confidence".
//
// Threading: everything here is a pure function of its arguments.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "infer/export.h"
#include "infer/pose_estimator.h"

namespace lmb {

struct LMB_INFER_EXPORT PoseEvidence {
  static constexpr int kNumFeatures = 7;
  int num_keypoints = 0;
  int num_correspondences = 0;  // usable correspondences offered to RANSAC
  int num_inliers = 0;
  int runner_up_inliers = 0;
  double inlier_rank = 0.5;  // see feature 3
  double spread = 0.0;       // see feature 4

  // The features in the order above.
  std::array<double, kNumFeatures> features() const;
  // Feature names, for reports ("log_inliers", "inlier_ratio", ...).
  static const std::array<const char*, kNumFeatures>& feature_names();
};

// The evidence of `pose` (estimate_absolute_pose's result on these pixels and quality; quality
// empty = no order: inlier rank 0.5) for a frame of num_keypoints keypoints. Throws lmb::Error on
// size mismatches or a negative num_keypoints.
LMB_INFER_EXPORT PoseEvidence pose_evidence(const Camera& camera, const std::vector<Eigen::Vector2d>& pixels,
                                            const std::vector<double>& quality, const PoseResult& pose,
                                            int num_keypoints);

// A logistic model of P(pose right | evidence) and its operating point.
struct LMB_INFER_EXPORT PoseCalibration {
  std::array<double, PoseEvidence::kNumFeatures> weights{};
  double bias = 0.0;
  // A pose counts as a success when its probability is at least this, in [0, 1].
  double threshold = 0.5;
  int64_t num_samples = 0;   // poses the model was fitted on (informative)
  int64_t num_positive = 0;  // of them right
  // The precision the threshold was chosen for on the fitted poses (informative), in [0, 1]; 0
  // when not set.
  double target_precision = 0.0;

  // sigma(bias + weights . features), in (0, 1); 0 when the evidence has no inlier.
  double probability(const PoseEvidence& evidence) const;
  // Fitted on samples that were all right: nothing told a wrong pose from a right one (the fit is
  // then the constant 0.5 with operating point 0, train/eval/pose_calibration_fit.h).
  bool saw_no_wrong_pose() const { return num_samples > 0 && num_positive == num_samples; }
  // bias + weights . features: the log-odds of probability(); -infinity when the evidence has no
  // inlier.
  double logit(const PoseEvidence& evidence) const;
  // Throws lmb::Error (prefixed by `where`) naming the field: non-finite weights or bias,
  // threshold outside [0, 1], negative or inconsistent counts.
  void check(const std::string& where = "pose calibration") const;
};

struct LMB_INFER_EXPORT PoseCalibrationFitOptions {
  // L2 penalty on the weights of the standardized features (not on the bias), > 0: keeps the fit
  // finite on separable data.
  double l2 = 1e-2;
  // Newton steps at most; the fit stops earlier when the step is below 1e-10.
  int max_iterations = 100;
  void check() const;  // throws lmb::Error naming the field
};

// Fits the logistic model to evidence[i] labelled right[i] (1 = the pose was right) by Newton's
// method (iteratively reweighted least squares) on the penalized log-likelihood, with features
// standardized on the samples (folded back into weights and bias). Deterministic: a function of
// the samples in their order. Poses without inliers are skipped (their probability is 0 by
// definition). Throws lmb::Error when the sizes differ or no sample has inliers. The threshold is
// left at 0.5; num_samples and num_positive count the samples used.
LMB_INFER_EXPORT PoseCalibration fit_pose_calibration(const std::vector<PoseEvidence>& evidence,
                                                      const std::vector<char>& right,
                                                      const PoseCalibrationFitOptions& options = {});

// The operating point for precision: the smallest threshold t among the probabilities such that
// the samples with probability >= t are right in at least a share `target_precision` (in (0, 1]),
// so that the most samples pass; 1 when no threshold reaches it (only poses of probability 1
// would pass). Throws lmb::Error when the sizes differ or target_precision is out of range.
LMB_INFER_EXPORT double precision_threshold(const std::vector<double>& probability, const std::vector<char>& right,
                                            double target_precision);

}  // namespace lmb
