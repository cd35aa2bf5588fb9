// The pose stage of `lboost eval`, the same for every method: a method's accepted matches of one
// query frame -> the correspondences given to LO-RANSAC (infer/pose_estimator.h: P3P, PROSAC in
// the order of the method's own confidence unless options.progressive_sampling is off) -> the frame's
// outcome (pose, inliers, times) that evaluate_poses (train/eval/metrics.h) scores.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "infer/pose_estimator.h"
#include "train/eval/matcher.h"
#include "train/eval/metrics.h"

namespace lmb {

// The 2D-3D correspondences of one frame, as given to estimate_absolute_pose, with the method's
// confidence in each (its PROSAC order: LandmarkBoost's margin over the background, a baseline's
// minus descriptor distance).
struct PoseInput {
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points_world;
  std::vector<double> quality;
};

// The accepted matches fed to RANSAC: all of them, or with max_correspondences > 0 the
// max_correspondences of largest confidence (ties: keypoint order), back in keypoint order. The
// same rule as the Localizer's with pose_top_k = 1 (where the confidence is the margin).
// Throws lmb::Error on max_correspondences < 0 or a keypoint index out of range.
PoseInput select_correspondences(const EvalQuery& query, const std::vector<Correspondence>& accepted,
                                 int max_correspondences);

// RANSAC on `input` with `options`: the frame's outcome with its truth, correspondence and inlier
// counts, confidence = inlier count and the pose's evidence. Times are left to the caller.
FrameOutcome estimate_frame_pose(const EvalQuery& query, const PoseInput& input, const PoseEstimatorOptions& options);

// The RANSAC budgets and seeds of the pose-recall sweep.
struct PoseSweepOptions {
  std::vector<int> iterations = {50, 100, 500};  // each >= 1 (PoseEstimatorOptions::max_iterations)
  int seeds = 5;       // seeds base, base + 1, ..., base + seeds - 1, base = the pose options' seed; >= 1
  void check() const;  // throws lmb::Error naming the field
};

// Adds one frame to `sweep` (set up by start_pose_sweep): RANSAC on `input` for every budget and
// seed, otherwise with `options`, counting the poses within `thresholds` of the truth, the poses
// reported by the inlier rule and, with a calibration (the sweep started with one), those the
// calibrated rule reports and how many of them are right. With per_seed, also the frame's outcome
// for each seed of the sweep at options.max_iterations (taken from the sweep when that budget is
// one of its budgets, else estimated; times left to the caller).
void sweep_frame_pose(const EvalQuery& query, const PoseInput& input, const PoseEstimatorOptions& options,
                      const PoseThresholds& thresholds, PoseSweep& sweep, const PoseCalibration* calibration = nullptr,
                      std::vector<FrameOutcome>* per_seed = nullptr);
// An empty sweep (no frame yet) of the budgets and seeds of `sweep_options` from base_seed; with
// calibrated, the calibrated counts too.
PoseSweep start_pose_sweep(const PoseSweepOptions& sweep_options, uint64_t base_seed, bool calibrated = false);

}  // namespace lmb
