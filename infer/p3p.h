// The minimal solver of the absolute pose (the first of the pose tiers: minimal solver ->
// ransac<Estimator> (infer/ransac.h) -> estimate_absolute_pose (infer/pose_estimator.h)):
// Kneip's P3P, through OpenGV, from three bearing vectors and their world points. Internal: not
// installed, not exported from liblmb_infer.so (estimate_absolute_pose is the public way in).
//
// Conventions: bearings are unit vectors in the camera frame (x right, y down, z forward); points
// are in the world frame; the solutions are cam_from_world (x_cam = R x_world + t), OpenGV's
// world_from_cam converted. No thresholds.
#pragma once

#include <vector>

#include <Eigen/Core>

namespace lmb {

// One cam_from_world pose as a rotation matrix and a translation (the form the estimators score).
struct CameraPose {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Vector3d center() const { return -(rotation.transpose() * translation); }
};

// Appends to *solutions the (up to 4) finite candidate poses of bearings[k] <-> points[k],
// k = 0, 1, 2, and returns how many were appended: OpenGV's p3p_kneip on the same sample, in its
// order. On exact data the true pose is among them; the others need not fit (Kneip's quartic
// gives the real parts of complex roots, and a point may land behind the camera), which the
// caller's scoring rejects. Degenerate input (collinear points, repeated bearings) gives 0
// solutions or poses that fit nothing; never throws. Thread-safe.
int p3p(const Eigen::Vector3d bearings[3], const Eigen::Vector3d points[3], std::vector<CameraPose>* solutions);

}  // namespace lmb
