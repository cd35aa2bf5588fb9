// Absolute camera pose from 2D-3D correspondences: P3P (Kneip) inside OpenGV's RANSAC, then a
// robust non-linear refinement on the inliers and a final inlier recount. This wrapper gives
// OpenGV pixels in, a cam_from_world pose out and a seeded, reproducible RANSAC.
//
// Conventions.
// - Pixels are in the distorted image with COLMAP's convention (centre of the top-left pixel at
//   (0.5, 0.5)); the camera model undistorts them (Camera::cam_from_img) into bearing vectors.
// - Points are in the world frame, in map units (metres for the maps this project builds).
// - The result is cam_from_world: x_cam = cam_from_world * x_world, camera frame x right, y down,
//   z forward. (OpenGV itself returns world_from_cam, i.e. the camera's rotation and centre in the
//   world; the wrapper converts.)
// - Inliers: correspondence i is an inlier when the angle between its observed bearing vector and
//   the direction from the camera to its point is below atan(max_reprojection_error_px / f), f the
//   camera's mean focal length; that is about max_reprojection_error_px pixels near the principal
//   point. Internally the threshold is OpenGV's 1 - cos(angle). A point behind the camera has an
//   angle above 90 degrees and is never an inlier.
//
// Errors. Invalid input throws lmb::Error: invalid options (check()), an invalid camera, pixel and
// point arrays of different sizes, a non-finite pixel or point. Having no answer is not an error:
// fewer than 4 correspondences, fewer than min_inliers inliers, fewer than 4 distinct inlier 3D
// points (duplicated correspondences) or a degenerate configuration give success == false.
//
// Threading: estimate_absolute_pose keeps no state between calls and may run concurrently from
// many threads. The result is a function of the inputs and options only (seed included), so the
// same call gives bit-identical results in any thread, any number of times.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/rigid3.h"
#include "infer/export.h"

namespace lmb {

struct LMB_INFER_EXPORT PoseEstimatorOptions {
  // Most RANSAC hypotheses (P3P samples) to evaluate, at least 2 (OpenGV's minimum); RANSAC stops
  // earlier once `confidence` is reached.
  int max_iterations = 500;
  // Inlier threshold in pixels (see the conventions above).
  double max_reprojection_error_px = 8.0;
  // Probability of having drawn at least one all-inlier sample before RANSAC stops early, in (0, 1).
  double confidence = 0.9999;
  // Seed of RANSAC's sampling: equal seeds (and inputs) give bit-identical results.
  uint64_t seed = 0;
  // Fewest inliers (after refinement) for success; at least 4.
  int min_inliers = 12;
  // Non-linear refinement on the inliers: Levenberg-Marquardt on the angular residuals with a
  // Cauchy loss (scale: half the inlier angle), then an inlier recount, repeated while the inlier
  // set changes (at most 4 rounds). A refinement is kept only when it does not raise the truncated
  // angular cost (MSAC) over all correspondences. (Not OpenGV's optimize_nonlinear, which
  // minimizes sum (1 - cos angle)^2 and is several times less accurate with noise.)
  bool refine = true;

  // Throws lmb::Error naming the field when a value is out of range.
  void check() const;
};

struct LMB_INFER_EXPORT PoseResult {
  // True when a pose with at least min_inliers inliers (and 4 distinct inlier points) was found.
  bool success = false;
  // The best pose found; meaningful only when success is true (identity when no hypothesis was
  // found at all).
  Rigid3d cam_from_world;
  // One entry per correspondence: 1 for the inliers of cam_from_world, 0 otherwise. Always sized
  // like the input.
  std::vector<char> inlier_mask;
  int num_inliers = 0;
  // RANSAC hypotheses evaluated (samples on which P3P failed are not counted).
  int iterations = 0;
};

// Estimates cam_from_world from pixels[i] <-> points_world[i] (same sizes). See the conventions
// and errors above. Runs in O(iterations * n).
LMB_INFER_EXPORT PoseResult estimate_absolute_pose(const Camera& camera,
                                                   const std::vector<Eigen::Vector2d>& pixels,
                                                   const std::vector<Eigen::Vector3d>& points_world,
                                                   const PoseEstimatorOptions& options = {});

}  // namespace lmb
