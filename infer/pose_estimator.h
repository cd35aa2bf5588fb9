// Absolute camera pose from 2D-3D correspondences, the third of the pose tiers: minimal solver
// (infer/p3p.h, Kneip's P3P) -> LO-RANSAC with PROSAC sampling (infer/ransac.h) ->
// estimate_absolute_pose, which takes pixels, undistorts them, orders the correspondences by the
// caller's quality (e.g. the classifier's margin), runs the loop with a robust non-linear local
// optimisation, and returns a cam_from_world pose with the loop's statistics and runner-up.
//
// Conventions.
// - Pixels are in the distorted image with COLMAP's convention (centre of the top-left pixel at
//   (0.5, 0.5)); the camera model undistorts them (Camera::cam_from_img) into bearing vectors.
// - Points are in the world frame, in map units (metres for the maps this project builds).
// - The result is cam_from_world: x_cam = cam_from_world * x_world, camera frame x right, y down,
//   z forward.
// - Inliers: correspondence i is an inlier when the angle between its observed bearing vector and
//   the direction from the camera to its point is below atan(max_reprojection_error_px / f), f the
//   camera's mean focal length; that is about max_reprojection_error_px pixels near the principal
//   point. Residuals are 1 - cos(angle); the MSAC score sums min(1 - cos(angle), threshold). A
//   point behind the camera has an angle above 90 degrees and is never an inlier.
// - Sampling: with a quality per correspondence (higher = more promising) and
//   progressive_sampling, PROSAC draws from the best-ranked correspondences first (ties keep the
//   input order); without one, samples are uniform. The stopping rules are PROSAC's (infer/ransac.h)
//   with beta = pi * max_reprojection_error_px^2 / image area and min_support = min_inliers.
// - Local optimisation (refine): Levenberg-Marquardt on the angular residuals of the inliers with a
//   Cauchy loss (scale: half the inlier angle), then an inlier recount, repeated while the inlier
//   set changes (at most 4 rounds); a refinement is kept only when it lowers the MSAC score. It
//   runs on every new best minimal model (LO-RANSAC) and on the runner-up.
//
// Errors. Invalid input throws lmb::Error: invalid options (check()), an invalid camera, pixel,
// point and quality arrays of different sizes, a non-finite pixel, point or quality. Having no
// answer is not an error: fewer than 4 usable correspondences, fewer than min_inliers inliers,
// fewer than 4 distinct inlier 3D points (duplicated correspondences) or a degenerate
// configuration give success == false.
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
#include "infer/ransac.h"

namespace lmb {

struct LMB_INFER_EXPORT PoseEstimatorOptions {
  // Most RANSAC samples (P3P calls), >= 1; the PROSAC/RANSAC stopping rules usually end earlier.
  int max_iterations = 500;
  // Fewest samples before a stopping rule may end the search (0..max_iterations).
  int min_iterations = 0;
  // Inlier threshold in pixels (see the conventions above).
  double max_reprojection_error_px = 8.0;
  // Probability that no better-supported pose was missed when RANSAC stops early, in (0, 1).
  double success_probability = 0.9999;
  // Seed of RANSAC's sampling: equal seeds (and inputs) give bit-identical results.
  uint64_t seed = 0;
  // Fewest inliers (after refinement) for success; at least 4. Also the least support of a
  // PROSAC stopping subset.
  int min_inliers = 12;
  // PROSAC when a quality order is given; false = uniform sampling always.
  bool progressive_sampling = true;
  // Local optimisation (see the conventions above); false = the best minimal model as it is.
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
  // The loop's statistics: samples, models scored, inlier count and ratio (over the usable
  // correspondences), MSAC score, refinements, PROSAC subsets, the runner-up's support.
  RansacStats stats;
  int iterations = 0;  // RANSAC samples drawn (= stats.iterations)
  // The runner-up pose (infer/ransac.h); meaningful when stats.runner_up_inliers > 0.
  Rigid3d runner_up_cam_from_world;
};

// Estimates cam_from_world from pixels[i] <-> points_world[i] (same sizes). quality: empty, or
// one finite value per correspondence, higher = sampled earlier (PROSAC). See the conventions and
// errors above. Runs in O(iterations * n + n log n).
LMB_INFER_EXPORT PoseResult estimate_absolute_pose(const Camera& camera, const std::vector<Eigen::Vector2d>& pixels,
                                                   const std::vector<Eigen::Vector3d>& points_world,
                                                   const PoseEstimatorOptions& options = {},
                                                   const std::vector<double>& quality = {});

// How many keypoints each pose explains when a keypoint may have several candidate 3D points
// (e.g. the matches of several area models, infer/area_bundle.h): keypoint k counts for a pose when
// at least one of points[k] passes the estimator's inlier test at it (the angle between the
// keypoint's bearing and the point seen from the pose within atan(max_reprojection_error_px / mean
// focal length), the point in front of the camera). pixels[k] as estimate_absolute_pose;
// points.size() == pixels.size(). A keypoint whose pixel does not undistort counts for nothing.
// Returns one count per pose (the bearings are computed once). With `unless_explained_by`, a
// point counts only when that pose does not explain it: a pose's support for a rival explanation
// of the frame (a pose that agrees with it counts ~0, a look-alike pose elsewhere its own support).
// Throws lmb::Error for mismatched sizes or a non-finite / non-positive threshold.
LMB_INFER_EXPORT std::vector<int> count_explained_keypoints(const Camera& camera,
                                                            const std::vector<Eigen::Vector2d>& pixels,
                                                            const std::vector<std::vector<Eigen::Vector3d>>& points,
                                                            const std::vector<Rigid3d>& cam_from_world,
                                                            double max_reprojection_error_px,
                                                            const Rigid3d* unless_explained_by = nullptr);
// The same from the keypoints' bearings (keypoint_bearings: each pixel through Camera::cam_from_img,
// as a unit vector; a non-finite one counts for nothing), for a caller counting many times a frame.
LMB_INFER_EXPORT std::vector<int> count_explained_keypoints(const Camera& camera,
                                                            const std::vector<Eigen::Vector3d>& bearings,
                                                            const std::vector<std::vector<Eigen::Vector3d>>& points,
                                                            const std::vector<Rigid3d>& cam_from_world,
                                                            double max_reprojection_error_px,
                                                            const Rigid3d* unless_explained_by = nullptr);
// The unit bearing of each pixel (camera.cam_from_img, normalized; non-finite where it does not
// undistort), as the estimator computes it.
LMB_INFER_EXPORT std::vector<Eigen::Vector3d> keypoint_bearings(const Camera& camera,
                                                                const std::vector<Eigen::Vector2d>& pixels);

}  // namespace lmb
