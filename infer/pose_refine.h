// The pose estimators' shared steps (inference's LO-RANSAC and the bench's OpenGV baseline):
// robust refinement of a camera pose and the count of distinct inlier points. Internal to the
// project (namespace detail), not part of the API.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "infer/p3p.h"

namespace lmb::detail {

// Robust non-linear refinement of cam_from_world (R, t) on the given correspondences, by
// Levenberg-Marquardt on angular residuals with a Cauchy loss.
//
// OpenGV's own optimize_nonlinear minimizes sum (1 - cos angle)^2, about sum angle^4 / 4: with
// noisy data that is far from the maximum-likelihood pose and lets a single false inlier near the
// threshold dominate (measured on test/infer/pose_estimator_test's scenes at 0.5 px noise and 50-80 %
// outliers: worst errors 15-25 mm and 0.31-0.41 degrees, against 2.5-4.7 mm and 0.035-0.050 here). This minimizes sum
// rho(|r_i|^2) where r_i is the 2D tangent-plane residual of the predicted direction at the observed bearing b_i (|r_i|
// = sin angle) and rho the Cauchy loss with scale `scale` (radians). bearings and points are indexed by `indices`; at
// most max_iterations steps, stopping once a step or the relative cost decrease is below `tolerance`.
CameraPose refine_cam_from_world(const Eigen::Vector3d* bearings, const Eigen::Vector3d* points,
                                 const std::vector<int>& indices, const CameraPose& start, double scale,
                                 int max_iterations, double tolerance = 1e-10);

// The number of distinct 3D points among points[inliers] (a pose needs 4 that differ).
int count_distinct_points(const std::vector<Eigen::Vector3d>& points, const std::vector<int>& inliers);

}  // namespace lmb::detail
