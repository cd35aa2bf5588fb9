// A small synthetic map for the tests of what is built from a map (export, descriptor fusion):
// pinhole 640 x 480 frames of random keypoints; `num_landmarks` landmarks with a base descriptor
// each, observed with probability `track_probability` by keypoint k = landmark id of every frame,
// `bit_flips` random bits flipped per observation; the other keypoints background with random
// descriptors. The last frame is a query frame. Deterministic for a seed.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/landmark_map.h"
#include "common/random.h"

namespace lmb::test {

struct SyntheticMapSpec {
  int descriptor_bytes = 16;
  int num_landmarks = 40;
  int num_frames = 8;
  int keypoints_per_frame = 150;
  double track_probability = 0.7;
  int bit_flips = 6;
  // Landmarks 1 .. twins-1 take the base descriptor of landmark (id % 2): twins that only the
  // context can tell apart (0: none).
  int twins = 0;
  // Gravity: a random roll in [-0.5, 0.5] rad per frame (true), or a fixed tilt cycling over three
  // values (false).
  bool random_roll = true;
};

inline LandmarkMap synthetic_map(uint64_t seed, const SyntheticMapSpec& spec) {
  const int bytes = spec.descriptor_bytes;
  Rng rng(seed);
  LandmarkMap map;
  map.descriptor_bytes = bytes;
  Camera cam;
  cam.model = CameraModel::kPinhole;
  cam.width = 640;
  cam.height = 480;
  cam.params = {500, 500, 320, 240};
  map.cameras = {cam};
  std::vector<std::vector<uint8_t>> base(spec.num_landmarks, std::vector<uint8_t>(bytes));
  for (auto& d : base) {
    for (auto& b : d) b = static_cast<uint8_t>(rng.below(256));
  }
  for (int l = 1; l < spec.twins; ++l) base[l] = base[l % 2];
  map.landmarks.resize(spec.num_landmarks);
  for (auto& l : map.landmarks) {
    l.position = Eigen::Vector3d(rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(3, 6));
    l.quality = 1.f;
  }
  const int query = spec.num_frames - 1;
  for (int f = 0; f < spec.num_frames; ++f) {
    MapFrame frame;
    frame.name = (f == query ? "query/" : "map/") + std::to_string(f);
    frame.is_query = f == query;
    if (spec.random_roll) {
      const double roll = rng.uniform(-0.5, 0.5);
      frame.gravity_in_cam = Eigen::Vector3d(std::sin(roll), std::cos(roll), 0.2).normalized();
    } else {
      frame.gravity_in_cam = Eigen::Vector3d(0.1 * (f % 3), 1.0, 0.2).normalized();
    }
    frame.first_keypoint = static_cast<int64_t>(map.keypoints.size());
    frame.num_keypoints = spec.keypoints_per_frame;
    map.frames.push_back(frame);
    for (int k = 0; k < spec.keypoints_per_frame; ++k) {
      map.keypoints.push_back(Keypoint{static_cast<float>(rng.uniform(0, 639)), static_cast<float>(rng.uniform(0, 479)),
                                       static_cast<float>(rng.uniform(10, 40)), -1.f});
      std::vector<uint8_t> desc(bytes);
      landmark_t id = kInvalidLandmarkId;
      if (k < spec.num_landmarks && rng.uniform() < spec.track_probability) {
        id = k;
        desc = base[k];
        for (int flip = 0; flip < spec.bit_flips; ++flip) {
          const int bit = static_cast<int>(rng.below(8 * bytes));
          desc[bit / 8] ^= static_cast<uint8_t>(1 << (bit % 8));
        }
        (f == query ? map.landmarks[id].num_query_observations : map.landmarks[id].num_map_observations)++;
      } else {
        for (auto& b : desc) b = static_cast<uint8_t>(rng.below(256));
      }
      map.keypoint_landmark.push_back(id);
      map.descriptors.insert(map.descriptors.end(), desc.begin(), desc.end());
    }
  }
  return map;
}

}  // namespace lmb::test
