// A corridor map for the area tests: 400 landmarks every 0.1 m along x (0..39.9 m), 80 map
// cameras every 0.5 m (x = 0..39.5) each seeing the landmarks with x in [cx - 1, cx + 4), and
// query cameras between map cameras (x = 5.1, 5.6, ..., 30.6) seeing the same span.
#pragma once

#include <cmath>
#include <vector>

#include "common/landmark_map.h"

namespace lmb::test {

inline LandmarkMap corridor_map() {
  LandmarkMap map;
  map.descriptor_bytes = 1;
  map.cameras.resize(1);
  const int num_landmarks = 400;
  for (int l = 0; l < num_landmarks; ++l) {
    Landmark lm;
    lm.position = Eigen::Vector3d(0.1 * l, 0.0, 1.0);
    map.landmarks.push_back(lm);
  }
  auto add_frame = [&](double cx, bool query) {
    MapFrame f;
    f.is_query = query;
    f.session = query ? 1 : 0;
    f.cam_from_world.translation = -Eigen::Vector3d(cx, 0.0, 1.5);
    f.first_keypoint = static_cast<int64_t>(map.keypoints.size());
    for (int l = 0; l < num_landmarks; ++l) {
      const double x = 0.1 * l;
      if (x >= cx - 1.0 - 1e-9 && x < cx + 4.0 - 1e-9) {
        map.keypoints.push_back({});
        map.keypoint_landmark.push_back(l);
        map.descriptors.push_back(0);
      }
    }
    map.keypoints.push_back({});  // one untracked keypoint
    map.keypoint_landmark.push_back(kInvalidLandmarkId);
    map.descriptors.push_back(0);
    f.num_keypoints = static_cast<int32_t>(map.keypoints.size() - f.first_keypoint);
    map.frames.push_back(f);
  };
  for (int f = 0; f < 80; ++f) add_frame(0.5 * f, false);
  for (int q = 0; q < 52; ++q) add_frame(5.1 + 0.5 * q, true);
  map.sessions = {{"map", SessionKind::kMap}, {"query", SessionKind::kQuery}};
  return map;
}

}  // namespace lmb::test
