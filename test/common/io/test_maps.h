// A small random but self-consistent landmark map for the map.h5 tests and the fuzz seeds.
#pragma once

#include <cstdint>
#include <string>

#include <Eigen/Geometry>

#include "common/landmark_map.h"
#include "common/random.h"

namespace lmb::test {

// A random but self-consistent map: 2 cameras, 3 sessions ("map": frames 0-1, "map-2": frame 2,
// "query": frames 3-4), 5 frames, 40 keypoints, 6 landmarks.
inline LandmarkMap random_map(uint64_t seed) {
  Rng rng(seed);
  LandmarkMap map;
  map.detector = "BRISK";
  map.descriptor_bytes = 64;
  Camera a;
  a.model = CameraModel::kOpenCV;
  a.width = 640;
  a.height = 480;
  a.params = {510.25, 490.5, 318.125, 241.0, -0.2, 0.05, 0.001, -0.002};
  Camera b;
  b.model = CameraModel::kSimpleRadial;
  b.width = 320;
  b.height = 240;
  b.params = {300.0, 160.0, 120.0, 0.01};
  map.cameras = {a, b};
  map.sessions = {{"map", SessionKind::kMap}, {"map-2", SessionKind::kMap}, {"query", SessionKind::kQuery}};
  const int num_landmarks = 6;
  map.landmarks.resize(num_landmarks);
  int64_t first = 0;
  for (int f = 0; f < 5; ++f) {
    MapFrame frame;
    frame.session = f < 2 ? 0 : f < 3 ? 1 : 2;
    frame.name = map.sessions[frame.session].name + "/" + std::to_string(f) + ".png";
    frame.camera = f % 2;
    frame.cam_from_world.rotation = Eigen::Quaterniond(
        Eigen::AngleAxisd(rng.uniform(-3, 3), Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal()).normalized()));
    frame.cam_from_world.translation = Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal());
    frame.gravity_in_cam = frame.cam_from_world.rotation * Eigen::Vector3d(0, 0, -1);
    frame.is_query = f >= 3;
    frame.first_keypoint = first;
    frame.num_keypoints = 8;
    first += 8;
    for (int k = 0; k < 8; ++k) {
      map.keypoints.push_back(Keypoint{static_cast<float>(rng.uniform(0, 640)), static_cast<float>(rng.uniform(0, 480)),
                                       static_cast<float>(rng.uniform(5, 40)),
                                       k == 0 ? -1.f : static_cast<float>(rng.uniform(0, 360))});
      for (int b2 = 0; b2 < 64; ++b2) map.descriptors.push_back(static_cast<uint8_t>(rng.below(256)));
      const landmark_t l = k < num_landmarks ? k : kInvalidLandmarkId;
      map.keypoint_landmark.push_back(l);
      if (l >= 0) ++(frame.is_query ? map.landmarks[l].num_query_observations : map.landmarks[l].num_map_observations);
    }
    map.frames.push_back(frame);
  }
  for (Landmark& l : map.landmarks) {
    l.position = Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal()) * 10.0;
    l.quality = static_cast<float>(rng.uniform(0, 5));
    l.mean_reprojection_error = static_cast<float>(rng.uniform(0, 2));
  }
  return map;
}

}  // namespace lmb::test
