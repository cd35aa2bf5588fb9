// Pose-guided matching of binary keypoints between two frames with known poses: a keypoint's
// candidates lie near its epipolar segment (the projection of its viewing ray between min_depth and
// max_depth) in the other image, found through a grid over the other image's keypoints instead of
// comparing all pairs. Accepted matches pass a Hamming threshold, a ratio test among the candidates
// and a mutual (both directions) check.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/rigid3.h"
#include "common/types.h"

namespace lmb {

struct MatchingOptions {
  double epipolar_threshold_px = 2.5;  // max distance to the epipolar segment, pixels of the other image
  double min_depth = 0.2;              // world units, along the optical axis of either camera
  double max_depth = 40.0;
  double max_hamming_fraction = 0.3;  // accepted distance <= fraction * descriptor bits
  double ratio = 0.9;                 // best distance < ratio * second best among the candidates
  double max_scale_change = 3.0;      // observed size ratio within [1/x, x] of the depth-predicted one; <= 0 off
  bool exhaustive_search = false;     // for tests: test every keypoint instead of walking the grid
  void check() const;                 // throws lmb::Error naming the field
};

// One frame prepared for matching: undistorted keypoints and a grid over them. The descriptors
// pointer must stay valid while the frame is used (num_keypoints rows of descriptor_bytes bytes).
class MatchingFrame {
 public:
  MatchingFrame(const Camera& camera, const Rigid3d& cam_from_world, const std::vector<Keypoint>& keypoints,
                const uint8_t* descriptors, int descriptor_bytes);

  int num_keypoints() const { return static_cast<int>(normalized_.size()); }

 private:
  friend class GuidedMatcher;
  const Camera* camera_;
  Rigid3d cam_from_world_;
  double focal_;                             // mean focal length, pixels
  std::vector<Eigen::Vector2d> normalized_;  // undistorted normalized coordinates per keypoint
  std::vector<float> scale_;                 // keypoint sizes, pixels
  const uint8_t* descriptors_;
  int descriptor_bytes_;
  // Grid over normalized coordinates: cell (cx, cy) holds keypoints [cell_start_[c], cell_start_[c + 1]).
  double cell_size_ = 0, min_x_ = 0, min_y_ = 0;
  int cells_x_ = 0, cells_y_ = 0;
  std::vector<int> cell_start_, cell_items_;
};

struct Match {
  int32_t a = 0;         // keypoint index in the first frame
  int32_t b = 0;         // keypoint index in the second frame
  int32_t distance = 0;  // Hamming distance
};

class GuidedMatcher {
 public:
  explicit GuidedMatcher(const MatchingOptions& options);

  // Mutual matches between frames a and b, sorted by a. Not thread-safe (scratch buffers); use one
  // matcher per thread.
  std::vector<Match> match(const MatchingFrame& a, const MatchingFrame& b);

  // One direction: best candidate in `to` for each keypoint of `from` (or -1), with its distance.
  void match_one_way(const MatchingFrame& from, const MatchingFrame& to, std::vector<int>* best,
                     std::vector<int>* best_distance);

 private:
  MatchingOptions options_;
  std::vector<uint32_t> stamp_;
  uint32_t stamp_value_ = 0;
  std::vector<int> best_ab_, dist_ab_, best_ba_, dist_ba_;
};

}  // namespace lmb
