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
                                         Eigen::AngleAxisd(-pitch, Eigen::Vector3d::UnitY()).toRotationMatrix() * base *
                                         Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Quaterniond q_cw(world_from_cam.transpose());
  Rigid3d pose(q_cw.normalized(), Eigen::Vector3d::Zero());
  pose.translation = -(pose.rotation * centre);
  return pose;
}

namespace {

constexpr double kDeg = M_PI / 180.0;

void add_pass(const World& world, const PassParams& p, double yaw_phase, int frames, uint64_t seed,
              std::vector<Rigid3d>* out) {
  if (frames <= 0) return;
  const double margin = 1.5;  // keeps cameras off the end walls
  const double x0 = margin, x1 = world.length - margin;
  const double step = frames > 1 ? (x1 - x0) / (frames - 1) : 0.0;
  Rng rng(seed);
  for (int i = 0; i < frames; ++i) {
    double s = frames > 1 ? i * step + p.sample_phase * step : 0.5 * (x1 - x0);
    s = std::clamp(s, 0.0, x1 - x0);
    const double x = p.heading == 0.0 ? x0 + s : x1 - s;
    const double tau = 2.0 * M_PI;
    const double y = p.lateral_m + 0.08 * std::sin(tau * s / 5.3 + yaw_phase) + rng.uniform(-0.02, 0.02);
    const double z = p.height_m + 0.04 * std::sin(tau * s / 1.4) + rng.uniform(-0.01, 0.01);
    const double yaw = p.heading + p.yaw_amplitude_deg * kDeg * std::sin(tau * s / p.yaw_period_m + yaw_phase) +
                       rng.uniform(-0.03, 0.03);
    const double pitch = p.pitch_mean_deg * kDeg +
                         p.pitch_amplitude_deg * kDeg * std::sin(tau * s / p.pitch_period_m + 1.3 * yaw_phase) +
                         rng.uniform(-0.01, 0.01);
    const double roll = p.roll_amplitude_deg * kDeg * std::sin(tau * s / 2.7 + 0.7) + rng.uniform(-0.01, 0.01);
    out->push_back(cam_from_world_pose(Eigen::Vector3d(x, y, z), yaw, pitch, roll));
  }
}

// How a session looks: its two passes (forward, backward) and its lighting. Lamp k of the world
// gets lamp_scale(k) (empty function: all lamps at 1).
struct SessionStyle {
  const char* time_of_day;
  PassParams forward, backward;
  double ambient, lamp_power, gain, exponent;
  int lamp_pattern;  // 0: all lamps on; 1: every 4th off; 2: alternate lamps at 0.55; 3: original
                     // query (every 3rd at 0.25, the others 0.8-1.2); 4: two of three at 0.3; 5: all 0.9
};

PassParams pass(double heading, double lateral, double height, double yaw_amp, double yaw_period, double pitch_mean,
                double pitch_amp, double pitch_period, double roll_amp, double phase) {
  return PassParams{heading,    lateral,   height,       yaw_amp,  yaw_period,
                    pitch_mean, pitch_amp, pitch_period, roll_amp, phase};
}

// Map session styles; row 0 is the world's original map session. Lanes, heights and lighting are
// spread over what people and robots walk (0.3-0.5 m off the centre, 1.35-1.75 m high; day, evening
// and night lighting); none equals a query style (test/train/world/trajectory_test).
SessionStyle map_style(int index) {
  switch (index) {
    case 0:
      return {"day, lamps on",
              pass(0, -0.3, 1.5, 50, 3.2, -4, 4, 2.3, 2, 0.0),
              pass(M_PI, 0.3, 1.5, 50, 3.2, -4, 4, 2.3, 2, 0.0),
              0.55,
              1.0,
              1.05,
              0.9,
              0};
    case 1:
      return {"evening, every 4th lamp off",
              pass(0, 0.35, 1.36, 44, 3.7, -1, 4, 2.6, 2.5, 0.25),
              pass(M_PI, -0.35, 1.38, 44, 3.7, -2, 4, 2.6, 2.5, 0.5),
              0.36,
              1.35,
              1.0,
              0.8,
              1};
    case 2:
      return {"bright day, lamps dim",
              pass(0, -0.5, 1.74, 56, 2.9, -9, 5, 2.0, 1.5, 0.6),
              pass(M_PI, -0.05, 1.70, 56, 2.9, -7, 5, 2.0, 1.5, 0.15),
              0.70,
              0.7,
              0.92,
              1.05,
              0};
    default:
      return {"night, alternate lamps dimmed",
              pass(0, 0.05, 1.44, 47, 3.5, -3, 3, 2.9, 3, 0.8),
              pass(M_PI, 0.5, 1.46, 47, 3.5, -3, 3, 2.9, 3, 0.35),
              0.28,
              1.55,
              1.15,
              0.7,
              2};
  }
}

// Query session styles; row 0 is the world's original query session.
SessionStyle query_style(int index) {
  switch (index) {
    case 0:
      return {"dim, every 3rd lamp low",
              pass(0, 0.1, 1.62, 38, 4.1, -7, 3, 3.1, 3, 0.37),
              pass(M_PI, -0.12, 1.58, 38, 4.1, -2, 3, 3.1, 3, 0.61),
              0.42,
              1.25,
              0.95,
              0.75,
              3};
    case 1:
      return {"dusk, two of three lamps low",
              pass(0, -0.6, 1.28, 32, 4.8, 1, 3, 3.4, 3.5, 0.13),
              pass(M_PI, 0.6, 1.25, 32, 4.8, 0, 3, 3.4, 3.5, 0.79),
              0.33,
              1.1,
              1.08,
              0.85,
              4};
    default:
      return {"sunny, lamps dim",
              pass(0, -0.02, 1.82, 60, 2.5, -10, 4, 2.2, 2, 0.45),
              pass(M_PI, 0.22, 1.80, 60, 2.5, -10, 4, 2.2, 2, 0.05),
              0.78,
              0.6,
              0.88,
              1.1,
              5};
  }
}

// `tag` keys the session's draws (phases, jitter, noise); session 0 of each kind keeps the draws
// of the world's original session.
Session make_session(const World& world, const SessionStyle& style, int frames, uint64_t tag, uint64_t index) {
  const uint64_t seed = world.options.seed;
  Rng rng(counter_hash(seed, tag, 0, index));
  Session s;
  s.time_of_day = style.time_of_day;
  s.passes[0] = style.forward;
  s.passes[1] = style.backward;
  const int forward = (frames + 1) / 2;
  const double phase_a = rng.uniform(0, 6.28), phase_b = rng.uniform(0, 6.28);
  add_pass(world, style.forward, phase_a, forward, counter_hash(seed, tag, 1, index), &s.cam_from_world);
  add_pass(world, style.backward, phase_b, frames - forward, counter_hash(seed, tag, 2, index), &s.cam_from_world);
  s.lighting.ambient = style.ambient;
  s.lighting.lamp_power = style.lamp_power;
  s.lighting.gain = style.gain;
  s.lighting.exponent = style.exponent;
  s.lighting.noise_sigma = world.options.noise_sigma;
  s.lighting.noise_seed = counter_hash(seed, tag, 3, index);
  if (style.lamp_pattern != 0) {
    for (size_t k = 0; k < world.lamps.size(); ++k) {
      double scale = 1.0;
      switch (style.lamp_pattern) {
        case 1: scale = k % 4 == 2 ? 0.0 : 1.0; break;
        case 2: scale = k % 2 == 1 ? 0.55 : 1.0; break;
        case 3: scale = k % 3 == 1 ? 0.25 : 0.8 + 0.4 * to_unit_double(counter_hash(seed, 0x1A3, k, index)); break;
        case 4: scale = k % 3 != 0 ? 0.3 : 1.0; break;
        default: scale = 0.9; break;
      }
      s.lighting.lamp_scale.push_back(scale);
    }
  }
  return s;
}

std::string session_name(const char* kind, int index) {
  return index == 0 ? std::string(kind) : std::string(kind) + "-" + std::to_string(index + 1);
}

}  // namespace

Session make_map_session(const World& world, int frames, int index) {
  LMB_CHECK(frames >= 1, "world: a map session needs >= 1 frame, got " << frames);
  LMB_CHECK(index >= 0 && index < kMaxMapSessions,
            "world: map session index " << index << " outside 0.." << kMaxMapSessions - 1);
  Session s = make_session(world, map_style(index), frames, 0x3A9, static_cast<uint64_t>(index));
  s.name = session_name("map", index);
  s.kind = SessionKind::kMap;
  s.frame_key_base = static_cast<uint64_t>(2 * index) << 32;
  return s;
}

Session make_query_session(const World& world, int frames, int index) {
  LMB_CHECK(frames >= 1, "world: a query session needs >= 1 frame, got " << frames);
  LMB_CHECK(index >= 0 && index < kMaxQuerySessions,
            "world: query session index " << index << " outside 0.." << kMaxQuerySessions - 1);
  Session s = make_session(world, query_style(index), frames, 0x9E7, static_cast<uint64_t>(index));
  s.name = session_name("query", index);
  s.kind = SessionKind::kQuery;
  s.frame_key_base = static_cast<uint64_t>(2 * index + 1) << 32;
  return s;
}

Rigid3d Session::recorded_cam_from_world(size_t i) const {
  // x_cam = R (x - offset) + t.
  Rigid3d pose = cam_from_world[i];
  pose.translation -= pose.rotation * world_offset;
  return pose;
}

Session make_outside_session(const World& outside_world, int frames) {
  LMB_CHECK(frames >= 1, "world: the outside session needs >= 1 frame, got " << frames);
  LMB_CHECK(outside_world.options.region == 1, "world: the outside session is rendered in the outside corridor");
  Session s = make_session(outside_world, query_style(0), frames, 0x0E5, 0);
  s.name = "outside";
  s.kind = SessionKind::kOutside;
  s.frame_key_base = static_cast<uint64_t>(9) << 32;
  s.world_offset = Eigen::Vector3d(0.0, kOutsideOffsetY, 0.0);
  return s;
}

std::vector<Session> make_world_sessions(const World& world) {
  const WorldOptions& o = world.options;
  o.check();
  std::vector<Session> sessions;
  for (int i = 0; i < o.map_sessions; ++i) {
    sessions.push_back(make_map_session(world, o.map_frames / o.map_sessions + (i < o.map_frames % o.map_sessions), i));
  }
  for (int j = 0; j < o.query_sessions; ++j) sessions.push_back(make_query_session(world, o.query_frames, j));
  return sessions;
}

}  // namespace lmb
