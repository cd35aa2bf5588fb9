#include "train/world/trajectory.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "common/error.h"
#include "common/random.h"

namespace lmb {

Camera world_camera(double scale) {
  Camera c;
  c.model = CameraModel::kOpenCV;
  c.width = static_cast<int>(std::lround(640 * scale));
  c.height = static_cast<int>(std::lround(480 * scale));
  const double sx = c.width / 640.0, sy = c.height / 480.0;
  c.params = {460.0 * sx, 460.0 * sy, 320.0 * sx, 240.0 * sy, -0.22, 0.05, 0.0008, -0.0005};
  return c;
}

Rigid3d cam_from_world_pose(const Eigen::Vector3d& centre, double yaw, double pitch, double roll) {
  Eigen::Matrix3d base;  // columns: camera x, y, z axes in the world for yaw = pitch = roll = 0
  base.col(0) = Eigen::Vector3d(0, -1, 0);
  base.col(1) = Eigen::Vector3d(0, 0, -1);
  base.col(2) = Eigen::Vector3d(1, 0, 0);
  const Eigen::Matrix3d world_from_cam = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                                         Eigen::AngleAxisd(-pitch, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                                         base * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Quaterniond q_cw(world_from_cam.transpose());
  Rigid3d pose(q_cw.normalized(), Eigen::Vector3d::Zero());
  pose.translation = -(pose.rotation * centre);
  return pose;
}

namespace {

struct PassSpec {
  double heading;       // 0 (+x) or pi (-x)
  double lateral;       // y of the walk
  double height;        // z of the camera
  double yaw_amp, yaw_period, yaw_phase;
  double pitch_mean, pitch_amp, pitch_period;
  double roll_amp;
  double phase_offset;  // fraction of a step by which the samples are shifted
};

void add_pass(const World& world, const PassSpec& p, int frames, uint64_t seed, std::vector<Rigid3d>* out) {
  if (frames <= 0) return;
  const double margin = 1.5;  // keeps cameras off the end walls
  const double x0 = margin, x1 = world.length - margin;
  const double step = frames > 1 ? (x1 - x0) / (frames - 1) : 0.0;
  Rng rng(seed);
  for (int i = 0; i < frames; ++i) {
    double s = frames > 1 ? i * step + p.phase_offset * step : 0.5 * (x1 - x0);
    s = std::clamp(s, 0.0, x1 - x0);
    const double x = p.heading == 0.0 ? x0 + s : x1 - s;
    const double tau = 2.0 * M_PI;
    const double y = p.lateral + 0.08 * std::sin(tau * s / 5.3 + p.yaw_phase) + rng.uniform(-0.02, 0.02);
    const double z = p.height + 0.04 * std::sin(tau * s / 1.4) + rng.uniform(-0.01, 0.01);
    const double yaw = p.heading + p.yaw_amp * std::sin(tau * s / p.yaw_period + p.yaw_phase) + rng.uniform(-0.03, 0.03);
    const double pitch = p.pitch_mean + p.pitch_amp * std::sin(tau * s / p.pitch_period + 1.3 * p.yaw_phase) +
                         rng.uniform(-0.01, 0.01);
    const double roll = p.roll_amp * std::sin(tau * s / 2.7 + 0.7) + rng.uniform(-0.01, 0.01);
    out->push_back(cam_from_world_pose(Eigen::Vector3d(x, y, z), yaw, pitch, roll));
  }
}

constexpr double kDeg = M_PI / 180.0;

}  // namespace

Session make_map_session(const World& world, int frames) {
  LMB_CHECK(frames >= 1, "world: --map-frames must be >= 1, got " << frames);
  const uint64_t seed = world.options.seed;
  Rng rng(counter_hash(seed, 0x3A9));
  Session s;
  s.name = "map";
  s.lateral_m = 0.3;
  s.height_m = 1.5;
  s.yaw_amplitude_deg = 50;
  s.yaw_period_m = 3.2;
  const int forward = (frames + 1) / 2;
  PassSpec a{0.0, -0.3, 1.5, 50 * kDeg, 3.2, rng.uniform(0, 6.28), -4 * kDeg, 4 * kDeg, 2.3, 2 * kDeg, 0.0};
  PassSpec b{M_PI, 0.3, 1.5, 50 * kDeg, 3.2, rng.uniform(0, 6.28), -4 * kDeg, 4 * kDeg, 2.3, 2 * kDeg, 0.0};
  add_pass(world, a, forward, counter_hash(seed, 0x3A9, 1), &s.cam_from_world);
  add_pass(world, b, frames - forward, counter_hash(seed, 0x3A9, 2), &s.cam_from_world);
  s.lighting.ambient = 0.55;
  s.lighting.lamp_power = 1.0;
  s.lighting.gain = 1.05;
  s.lighting.exponent = 0.9;
  s.lighting.noise_sigma = world.options.noise_sigma;
  s.lighting.noise_seed = counter_hash(seed, 0x3A9, 3);
  return s;
}

Session make_query_session(const World& world, int frames) {
  LMB_CHECK(frames >= 1, "world: --query-frames must be >= 1, got " << frames);
  const uint64_t seed = world.options.seed;
  Rng rng(counter_hash(seed, 0x9E7));
  Session s;
  s.name = "query";
  s.lateral_m = 0.1;
  s.height_m = 1.62;
  s.yaw_amplitude_deg = 38;
  s.yaw_period_m = 4.1;
  const int forward = (frames + 1) / 2;
  PassSpec a{0.0, 0.1, 1.62, 38 * kDeg, 4.1, rng.uniform(0, 6.28), -7 * kDeg, 3 * kDeg, 3.1, 3 * kDeg, 0.37};
  PassSpec b{M_PI, -0.12, 1.58, 38 * kDeg, 4.1, rng.uniform(0, 6.28), -2 * kDeg, 3 * kDeg, 3.1, 3 * kDeg, 0.61};
  add_pass(world, a, forward, counter_hash(seed, 0x9E7, 1), &s.cam_from_world);
  add_pass(world, b, frames - forward, counter_hash(seed, 0x9E7, 2), &s.cam_from_world);
  s.lighting.ambient = 0.42;
  s.lighting.lamp_power = 1.25;
  s.lighting.gain = 0.95;
  s.lighting.exponent = 0.75;
  s.lighting.noise_sigma = world.options.noise_sigma;
  s.lighting.noise_seed = counter_hash(seed, 0x9E7, 3);
  for (size_t k = 0; k < world.lamps.size(); ++k) {
    s.lighting.lamp_scale.push_back(k % 3 == 1 ? 0.25 : 0.8 + 0.4 * to_unit_double(counter_hash(seed, 0x1A3, k)));
  }
  return s;
}

}  // namespace lmb
