// Checks a landmark map against the exact depth maps a rendered world writes
// (DIR/depth/<image name>: 16-bit PNG, z-depth of each pixel centre in millimetres, 0 = none):
// every landmark observation is back-projected with its depth and pose, and the track is judged by
// how tightly those points agree (purity) and how far the triangulated landmark lies from them.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include <Eigen/Core>

#include "common/landmark_map.h"

namespace lmb {

// Back-projects keypoints of `frame` with the depth image `depth_mm` (CV_16UC1 as read from the
// depth PNG); points without depth are NaN. Keypoints use COLMAP pixel coordinates; the depth of
// the pixel whose centre is nearest is used.
std::vector<Eigen::Vector3d> back_project_keypoints(const LandmarkMap& map, frame_t frame, const uint16_t* depth_mm,
                                                    int width, int height);

struct DepthCheckOptions {
  double purity_radius_m = 0.05;  // an observation agrees with its track within this distance
};

struct MapAccuracy {
  int64_t landmarks_checked = 0;  // landmarks with >= 2 observations that have depth
  int64_t observations_checked = 0;
  int64_t observations_without_depth = 0;
  double mean_track_purity = 0;        // mean over landmarks of the agreeing share
  double observation_purity = 0;       // agreeing observations / all checked observations
  double pure_track_share = 0;         // landmarks whose every observation agrees
  double median_position_error_m = 0;  // |landmark - majority point|
  double mean_position_error_m = 0;
  double p90_position_error_m = 0;
};

// Reads the depth images of every frame under `collection_dir`/depth and checks `map`. The
// majority point of a track is the mean of the largest group of its back-projected observations
// lying within purity_radius_m of one of them. Throws lmb::Error when a depth image is missing,
// unreadable or not 16-bit of the camera's size.
MapAccuracy check_map_against_depth(const LandmarkMap& map, const std::filesystem::path& collection_dir,
                                    const DepthCheckOptions& options = {});

}  // namespace lmb
