// Triangulation of one track from frames with known poses: OpenGV two-view triangulation
// (triangulate2) on candidate pairs of observations, the hypothesis with most inliers kept, then
// Gauss-Newton refinement on the inliers' reprojection errors, repeated until the inlier set is
// stable.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/rigid3.h"

namespace lmb {

struct TriangulationOptions {
  double max_reprojection_error_px = 3.0;    // an observation is an inlier below this
  double min_triangulation_angle_deg = 2.0;  // largest angle between two inlier rays at the point
  int max_pair_hypotheses = 40;              // OpenGV two-view hypotheses tried per track
  int refine_iterations = 10;                // Gauss-Newton steps per refinement
  void check() const;                        // throws lmb::Error naming the field
};

struct TrackObservation {
  const Camera* camera = nullptr;
  Rigid3d cam_from_world;
  Eigen::Vector2d pixel;  // distorted image coordinates (COLMAP convention)
};

struct TriangulatedPoint {
  bool success = false;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // world frame
  std::vector<bool> inlier;                            // per observation
  int num_inliers = 0;
  double mean_reprojection_error_px = 0;  // over the inliers
  double triangulation_angle_deg = 0;     // largest angle between two inlier rays
};

// Triangulates `observations` (>= 2). success means >= 2 inliers in front of their cameras with
// reprojection error below the threshold and a triangulation angle above the minimum.
TriangulatedPoint triangulate_track(const std::vector<TrackObservation>& observations,
                                    const TriangulationOptions& options);

// Pixel reprojection error of a world point in one observation; +infinity behind the camera.
double reprojection_error_px(const TrackObservation& observation, const Eigen::Vector3d& point_in_world);

}  // namespace lmb
