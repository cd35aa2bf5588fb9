// Refinement of camera intrinsics on a map's own tracks with the poses held fixed: the focal length
// (fx and fy scaled together, so their ratio stays) and optionally the principal point of each
// camera, jointly with the tracks' 3D points, minimizing a robust (Huber) sum of squared pixel
// reprojection errors by Levenberg-Marquardt. The points are eliminated per track (Schur
// complement), so each step solves a system of (1 or 3) x cameras unknowns. Distortion parameters
// are kept (they act on normalized coordinates and do not change with the focal length).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/rigid3.h"
#include "common/types.h"

namespace lmb {

struct CameraRefinementOptions {
  bool principal_point = false;  // also cx, cy
  int max_iterations = 15;       // Levenberg-Marquardt steps
  double huber_px = 2.0;         // robust loss: quadratic below, linear above this error (pixels)
  // A camera with fewer observations keeps its intrinsics (too little to estimate them).
  int min_observations = 50;
  void check() const;  // throws lmb::Error naming the field
};

// One track to refine on: its observations (frame index and distorted pixel) and a start point.
struct RefinementTrack {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // world
  std::vector<int> frames;                             // index into the frames' poses and cameras
  std::vector<Eigen::Vector2d> pixels;                 // per observation, COLMAP pixel convention
};

struct CameraRefinementResult {
  std::vector<Camera> cameras;               // refined (or unchanged: too few observations)
  std::vector<int64_t> observations;         // per camera
  std::vector<double> mean_error_before_px;  // per camera, plain mean reprojection error
  std::vector<double> mean_error_after_px;   // per camera, with the refined points and camera
  std::vector<Eigen::Vector3d> positions;    // refined track points (world)
  int iterations = 0;                        // steps taken
};

// Refines `cameras` (indexed by frame_camera[frame]) on `tracks` observed in frames whose poses are
// cam_from_world. Observations behind their camera are ignored. Throws lmb::Error on inconsistent
// sizes or indices.
CameraRefinementResult refine_cameras(const std::vector<Camera>& cameras, const std::vector<Rigid3d>& cam_from_world,
                                      const std::vector<camera_t>& frame_camera,
                                      const std::vector<RefinementTrack>& tracks,
                                      const CameraRefinementOptions& options);

// The camera with its focal length(s) multiplied by `scale` and its principal point moved by
// `shift` pixels.
Camera scaled_camera(const Camera& camera, double scale, const Eigen::Vector2d& shift = Eigen::Vector2d::Zero());

}  // namespace lmb
