// The landmark map: what `lboost map` produces and everything downstream reads. Plain data; the
// HDF5 file format lives in common/io/map_h5.h.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/rigid3.h"
#include "common/types.h"

namespace lmb {

struct MapFrame {
  std::string name;               // image name in the collection ("map/000012.png")
  camera_t camera = 0;            // index into LandmarkMap::cameras
  Rigid3d cam_from_world;
  Eigen::Vector3d gravity_in_cam = Eigen::Vector3d(0, 1, 0);  // unit, pointing down, camera frame
  bool is_query = false;          // query frames and their keypoints never reach training
  int64_t first_keypoint = 0;     // this frame's keypoints are [first, first + num)
  int32_t num_keypoints = 0;
};

struct Landmark {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // world frame
  float quality = 0.f;               // higher is better; used for top-K selection
  float mean_reprojection_error = 0.f;  // pixels, over all observations
  int32_t num_map_observations = 0;
  int32_t num_query_observations = 0;
};

struct LandmarkMap {
  std::string detector = "BRISK";
  int descriptor_bytes = 0;
  std::vector<Camera> cameras;
  std::vector<MapFrame> frames;
  std::vector<Keypoint> keypoints;            // all frames' keypoints, frame after frame
  std::vector<uint8_t> descriptors;           // keypoints.size() * descriptor_bytes
  std::vector<landmark_t> keypoint_landmark;  // per keypoint: its landmark or kInvalidLandmarkId
  std::vector<Landmark> landmarks;

  const uint8_t* descriptor(int64_t keypoint) const {
    return descriptors.data() + keypoint * descriptor_bytes;
  }
  frame_t num_frames() const { return static_cast<frame_t>(frames.size()); }
};

}  // namespace lmb
