// A mapper-free estimate of how many landmarks a rendered world yields: BRISK keypoints (OpenCV
// defaults) of the map images are back-projected with their exact depth and pose and
// merged into points (greedy clustering within a radius), and a point seen in k distinct map frames
// counts as a landmark of k observations.
#pragma once

#include <cstdint>
#include <filesystem>

namespace lmb {

struct LandmarkStats {
  int map_frames = 0;
  int query_frames = 0;
  int64_t map_keypoints = 0;
  int64_t points = 0;        // distinct 3D points (clusters) of map keypoints
  int64_t landmarks_3 = 0;   // points seen in >= 3 map frames
  int64_t landmarks_10 = 0;  // points seen in >= 10 map frames
  int64_t query_keypoints = 0;
  int64_t query_on_landmark = 0;  // query keypoints within the radius of a >= 3-frame landmark
  double seconds = 0.0;
};

// Reads DIR/sparse, DIR/images and DIR/depth of a world folder. `voxel_m` is the merge radius (m).
// Throws lmb::Error when a file is missing or unreadable.
LandmarkStats estimate_landmarks(const std::filesystem::path& world_dir, double voxel_m = 0.01);

}  // namespace lmb
