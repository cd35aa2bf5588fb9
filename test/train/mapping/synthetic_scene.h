// Test helper: a synthetic corridor (points on walls, floor and ceiling) seen by map and query
// cameras with lens distortion; keypoints are exact projections plus pixel noise, descriptors are a
// per-point pattern with random bit flips, plus clutter keypoints with random descriptors. With
// num_patterns < num_points, points share descriptor patterns (aliasing).
#pragma once

#include <cmath>
#include <vector>

#include "common/camera.h"
#include "common/random.h"
#include "common/rigid3.h"
#include "train/mapping/mapper.h"

namespace lmb::test {

struct SyntheticSceneOptions {
  uint64_t seed = 1;
  int num_points = 2500;
  int num_patterns = 0;         // 0: every point has its own descriptor pattern
  int unique_bits = 0;          // with patterns: bits flipped per point on top of its pattern
  double bit_flip_rate = 0.04;  // per observation
  double pixel_noise = 0.3;     // standard deviation, pixels
  int num_map_frames = 30;
  double map_spacing = 0.4;  // metres between map frames along the corridor
  double map_wobble = 0.3;   // amplitude of their sideways and yaw wobble (metres; x 0.5 = radians)
  int num_query_frames = 8;  // at random poses along the corridor, unless query_poses is given
  std::vector<Rigid3d> query_poses;
  int clutter_per_frame = 40;
  int descriptor_bytes = 64;
};

struct SyntheticScene {
  Camera camera;
  std::vector<Eigen::Vector3d> points;
  std::vector<MapperFrame> frames;
  std::vector<std::vector<int>> keypoint_point;  // per frame, per keypoint: point index or -1
};

// Pose looking along yaw (radians from +x, about +z = up) from `center`.
inline Rigid3d look_along(const Eigen::Vector3d& center, double yaw, double pitch = 0.0) {
  const Eigen::Vector3d forward(std::cos(yaw) * std::cos(pitch), std::sin(yaw) * std::cos(pitch), std::sin(pitch));
  const Eigen::Vector3d right = Eigen::Vector3d(0, 0, -1).cross(forward).normalized();
  const Eigen::Vector3d down = forward.cross(right);
  Eigen::Matrix3d world_from_cam;
  world_from_cam << right, down, forward;
  const Eigen::Quaterniond q(world_from_cam.transpose());
  return Rigid3d(q.normalized(), -(world_from_cam.transpose() * center));
}

inline SyntheticScene make_synthetic_scene(const SyntheticSceneOptions& o) {
  SyntheticScene s;
  Rng rng(o.seed);
  s.camera.model = CameraModel::kOpenCV;
  s.camera.width = 640;
  s.camera.height = 480;
  s.camera.params = {500, 500, 320, 240, -0.08, 0.01, 0.0005, -0.0003};
  for (int i = 0; i < o.num_points; ++i) {
    const double x = rng.uniform(-1, 26);
    const int face = static_cast<int>(rng.below(4));
    if (face == 0) s.points.emplace_back(x, -2.0, rng.uniform(0, 3));
    if (face == 1) s.points.emplace_back(x, 2.0, rng.uniform(0, 3));
    if (face == 2) s.points.emplace_back(x, rng.uniform(-2, 2), 0.0);
    if (face == 3) s.points.emplace_back(x, rng.uniform(-2, 2), 3.0);
  }
  const int bytes = o.descriptor_bytes;
  const int patterns = o.num_patterns > 0 ? o.num_patterns : o.num_points;
  std::vector<uint8_t> pattern(static_cast<size_t>(patterns) * bytes);
  for (auto& b : pattern) b = static_cast<uint8_t>(rng.below(256));
  std::vector<uint8_t> point_desc(static_cast<size_t>(o.num_points) * bytes);
  for (int p = 0; p < o.num_points; ++p) {
    std::copy_n(pattern.begin() + static_cast<size_t>(p % patterns) * bytes, bytes,
                point_desc.begin() + static_cast<size_t>(p) * bytes);
    for (int u = 0; u < o.unique_bits; ++u) {
      const int bit = static_cast<int>(rng.below(8 * bytes));
      point_desc[static_cast<size_t>(p) * bytes + bit / 8] ^= static_cast<uint8_t>(1 << (bit % 8));
    }
  }
  auto add_frame = [&](const Rigid3d& pose, bool is_query, int index) {
    MapperFrame f;
    f.name = (is_query ? "query/" : "map/") + std::to_string(index) + ".png";
    f.camera = 0;
    f.cam_from_world = pose;
    f.is_query = is_query;
    std::vector<int> gt;
    for (int p = 0; p < o.num_points; ++p) {
      const Eigen::Vector3d pc = pose * s.points[p];
      if (pc.z() < 0.3 || pc.z() > 15) continue;
      Eigen::Vector2d px;
      if (!s.camera.project(pc, &px)) continue;
      px += Eigen::Vector2d(rng.normal(), rng.normal()) * o.pixel_noise;
      if (px.x() < 10 || px.y() < 10 || px.x() > 630 || px.y() > 470) continue;
      f.keypoints.push_back(Keypoint{static_cast<float>(px.x()), static_cast<float>(px.y()),
                                     static_cast<float>(60.0 / pc.z()), static_cast<float>(rng.uniform(0, 360))});
      for (int b = 0; b < bytes; ++b) {
        uint8_t v = point_desc[static_cast<size_t>(p) * bytes + b];
        for (int bit = 0; bit < 8; ++bit) {
          if (rng.uniform() < o.bit_flip_rate) v ^= static_cast<uint8_t>(1 << bit);
        }
        f.descriptors.push_back(v);
      }
      gt.push_back(p);
    }
    for (int c = 0; c < o.clutter_per_frame; ++c) {
      f.keypoints.push_back(Keypoint{static_cast<float>(rng.uniform(10, 630)), static_cast<float>(rng.uniform(10, 470)),
                                     static_cast<float>(rng.uniform(8, 40)), -1.f});
      for (int b = 0; b < bytes; ++b) f.descriptors.push_back(static_cast<uint8_t>(rng.below(256)));
      gt.push_back(-1);
    }
    s.frames.push_back(std::move(f));
    s.keypoint_point.push_back(std::move(gt));
  };
  for (int i = 0; i < o.num_map_frames; ++i) {
    const double x = o.map_spacing * i;
    add_frame(
        look_along(Eigen::Vector3d(x, o.map_wobble * std::sin(0.7 * i), 1.5), 0.5 * o.map_wobble * std::sin(0.5 * i)),
        false, i);
  }
  for (size_t i = 0; i < o.query_poses.size(); ++i) add_frame(o.query_poses[i], true, static_cast<int>(i));
  for (int i = 0; i < (o.query_poses.empty() ? o.num_query_frames : 0); ++i) {
    const double x = 0.5 + 1.3 * i;
    add_frame(
        look_along(Eigen::Vector3d(x, rng.uniform(-0.6, 0.6), 1.3), rng.uniform(-0.3, 0.3), rng.uniform(-0.1, 0.1)),
        true, i);
  }
  return s;
}

}  // namespace lmb::test
