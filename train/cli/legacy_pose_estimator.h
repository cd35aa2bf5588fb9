// The pose estimator LandmarkBoost had before its own LO-RANSAC (infer/ransac.h): P3P (KNEIP, four
// points a sample) in OpenGV's RANSAC with uniform sampling and adaptive stopping, then the robust
// refinement on the inliers. Kept, unchanged, as the baseline of `lboost bench pose`, so that the
// comparison runs both on the same correspondences in the same process.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/rigid3.h"

namespace lmb::legacy {

struct LegacyPoseOptions {
  int max_iterations = 500;  // hypotheses (OpenGV's evaluates at least 2)
  double max_reprojection_error_px = 8.0;
  double confidence = 0.9999;  // OpenGV's adaptive stopping
  uint64_t seed = 0;
  int min_inliers = 12;
  bool refine = true;
};

struct LegacyPoseResult {
  bool success = false;
  Rigid3d cam_from_world;
  int num_inliers = 0;
  int iterations = 0;
};

// As the old estimate_absolute_pose (same inputs, conventions and seeded sampling); no checks.
LegacyPoseResult estimate_absolute_pose(const Camera& camera, const std::vector<Eigen::Vector2d>& pixels,
                                        const std::vector<Eigen::Vector3d>& points_world,
                                        const LegacyPoseOptions& options);

}  // namespace lmb::legacy
