#include "train/world/trajectory.h"

#include <cmath>
#include <set>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

Eigen::Vector3d world_dir(const Rigid3d& cam_from_world, const Eigen::Vector3d& cam_dir) {
  return cam_from_world.rotation.conjugate() * cam_dir;
}

TEST(TrajectoryTest, PoseAxes) {
  const Eigen::Vector3d c(3.0, -0.2, 1.5);
  const double yaw = 0.7;
  const Rigid3d p = cam_from_world_pose(c, yaw, 0.0, 0.0);
  EXPECT_LT((p.center() - c).norm(), 1e-12);
  EXPECT_LT((world_dir(p, Eigen::Vector3d::UnitZ()) - Eigen::Vector3d(std::cos(yaw), std::sin(yaw), 0)).norm(), 1e-12);
  EXPECT_LT((world_dir(p, Eigen::Vector3d::UnitY()) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);  // down = -z
  // Right = forward x up.
  EXPECT_LT((world_dir(p, Eigen::Vector3d::UnitX()) - Eigen::Vector3d(std::sin(yaw), -std::cos(yaw), 0)).norm(), 1e-12);
  // Positive pitch looks up.
  const Rigid3d up = cam_from_world_pose(c, yaw, 0.2, 0.0);
  EXPECT_NEAR(world_dir(up, Eigen::Vector3d::UnitZ()).z(), std::sin(0.2), 1e-12);
  // Roll keeps the optical axis.
  const Rigid3d rolled = cam_from_world_pose(c, yaw, 0.0, 0.3);
  EXPECT_LT((world_dir(rolled, Eigen::Vector3d::UnitZ()) - world_dir(p, Eigen::Vector3d::UnitZ())).norm(), 1e-12);
  EXPECT_NEAR(world_dir(rolled, Eigen::Vector3d::UnitY()).z(), -std::cos(0.3), 1e-12);
}

TEST(TrajectoryTest, SessionsStayInsideTheCorridorUprightAndDiffer) {
  const World w = build_world(world_preset("tiny"));
  const Session map = make_map_session(w, 30);
  const Session query = make_query_session(w, 10);
  ASSERT_EQ(map.cam_from_world.size(), 30u);
  ASSERT_EQ(query.cam_from_world.size(), 10u);
  for (const Session* s : {&map, &query}) {
    for (const Rigid3d& p : s->cam_from_world) {
      const Eigen::Vector3d c = p.center();
      EXPECT_GT(c.x(), 1.0);
      EXPECT_LT(c.x(), w.length - 1.0);
      EXPECT_LT(std::abs(c.y()), 0.5);
      EXPECT_GT(c.z(), 1.3);
      EXPECT_LT(c.z(), 1.8);
      // The camera's up (-y) is within 15 degrees of world +z (gravity along -z).
      EXPECT_GT(world_dir(p, -Eigen::Vector3d::UnitY()).z(), std::cos(15.0 * M_PI / 180.0));
      EXPECT_NEAR(p.rotation.norm(), 1.0, 1e-12);
    }
  }
  // Both directions are walked, and the sessions differ in pose and lighting.
  int forward = 0;
  for (const Rigid3d& p : map.cam_from_world) forward += world_dir(p, Eigen::Vector3d::UnitZ()).x() > 0;
  EXPECT_GT(forward, 5);
  EXPECT_LT(forward, 25);
  EXPECT_GT((map.cam_from_world[0].center() - query.cam_from_world[0].center()).norm(), 0.1);
  EXPECT_NE(map.lighting.gain, query.lighting.gain);
  EXPECT_EQ(query.lighting.lamp_scale.size(), w.lamps.size());
  EXPECT_THROW(make_map_session(w, 0), Error);
  EXPECT_THROW(make_query_session(w, 0), Error);
}

// Every session of every kind: deterministic for a seed, inside the corridor and upright; session 0
// of a kind does not depend on how many sessions the world has.
TEST(TrajectoryTest, MultiSessionWorldsAreDeterministicAndInsideTheCorridor) {
  WorldOptions o = world_preset("tiny");
  o.map_sessions = kMaxMapSessions;
  o.query_sessions = kMaxQuerySessions;
  o.map_frames = 42;  // 11, 11, 10, 10
  o.query_frames = 6;
  const World w = build_world(o);
  const std::vector<Session> a = make_world_sessions(w), b = make_world_sessions(w);
  ASSERT_EQ(a.size(), static_cast<size_t>(kMaxMapSessions + kMaxQuerySessions));
  const char* names[] = {"map", "map-2", "map-3", "map-4", "query", "query-2", "query-3"};
  const int frames[] = {11, 11, 10, 10, 6, 6, 6};
  std::set<uint64_t> keys;
  for (size_t s = 0; s < a.size(); ++s) {
    EXPECT_EQ(a[s].name, names[s]);
    EXPECT_EQ(a[s].kind, s < 4 ? SessionKind::kMap : SessionKind::kQuery);
    ASSERT_EQ(a[s].cam_from_world.size(), static_cast<size_t>(frames[s])) << a[s].name;
    EXPECT_TRUE(keys.insert(a[s].frame_key_base).second) << a[s].name;
    EXPECT_TRUE(keys.insert(a[s].lighting.noise_seed).second) << a[s].name;
    for (size_t i = 0; i < a[s].cam_from_world.size(); ++i) {
      const Rigid3d& p = a[s].cam_from_world[i];
      EXPECT_EQ(p.rotation.coeffs(), b[s].cam_from_world[i].rotation.coeffs());
      EXPECT_EQ(p.translation, b[s].cam_from_world[i].translation);
      const Eigen::Vector3d c = p.center();
      EXPECT_GT(c.x(), 1.0);
      EXPECT_LT(c.x(), w.length - 1.0);
      EXPECT_LT(std::abs(c.y()), 0.75) << a[s].name;  // pillars stand 0.95 m off the centre
      EXPECT_GT(c.z(), 1.15) << a[s].name;
      EXPECT_LT(c.z(), 1.9) << a[s].name;
      EXPECT_GT(world_dir(p, -Eigen::Vector3d::UnitY()).z(), std::cos(15.0 * M_PI / 180.0));
    }
    EXPECT_TRUE(a[s].lighting.lamp_scale.empty() || a[s].lighting.lamp_scale.size() == w.lamps.size());
  }
  // Session 0 of each kind is the world's original session, whatever the session count.
  const Session map0 = make_map_session(w, 11), query0 = make_query_session(w, 6);
  for (size_t i = 0; i < 11; ++i) EXPECT_EQ(map0.cam_from_world[i].translation, a[0].cam_from_world[i].translation);
  for (size_t i = 0; i < 6; ++i) EXPECT_EQ(query0.cam_from_world[i].translation, a[4].cam_from_world[i].translation);
  EXPECT_EQ(map0.frame_key_base, 0u);
  EXPECT_EQ(query0.frame_key_base, uint64_t{1} << 32);
  // Another seed moves every session.
  o.seed = 2;
  const std::vector<Session> c = make_world_sessions(build_world(o));
  for (size_t s = 0; s < a.size(); ++s) {
    EXPECT_NE(a[s].cam_from_world[1].translation, c[s].cam_from_world[1].translation) << a[s].name;
  }
  EXPECT_THROW(make_map_session(w, 5, kMaxMapSessions), Error);
  EXPECT_THROW(make_query_session(w, 5, -1), Error);
}

// Each query session is unlike every map session: another camera height or lanes, and other
// lighting.
TEST(TrajectoryTest, EveryQuerySessionIsUnlikeEveryMapSession) {
  const World w = build_world(world_preset("tiny"));
  for (int m = 0; m < kMaxMapSessions; ++m) {
    const Session map = make_map_session(w, 10, m);
    for (int q = 0; q < kMaxQuerySessions; ++q) {
      const Session query = make_query_session(w, 10, q);
      double height = 0, lanes = 0;
      for (int p = 0; p < 2; ++p) {
        height = std::max(height, std::abs(map.passes[p].height_m - query.passes[p].height_m));
        lanes = std::max(lanes, std::abs(map.passes[p].lateral_m - query.passes[p].lateral_m));
      }
      EXPECT_TRUE(height >= 0.08 || lanes >= 0.15) << map.name << " vs " << query.name;
      EXPECT_TRUE(std::abs(map.lighting.ambient - query.lighting.ambient) >= 0.05 ||
                  std::abs(map.lighting.lamp_power - query.lighting.lamp_power) >= 0.1)
          << map.name << " vs " << query.name;
    }
    for (int n = 0; n < m; ++n) {  // map sessions differ from each other too
      const Session other = make_map_session(w, 10, n);
      EXPECT_GE(std::abs(map.passes[0].height_m - other.passes[0].height_m) +
                    std::abs(map.passes[0].lateral_m - other.passes[0].lateral_m),
                0.1)
          << map.name << " vs " << other.name;
      EXPECT_NE(map.lighting.ambient, other.lighting.ambient);
    }
  }
  WorldOptions o = world_preset("tiny");
  o.map_sessions = kMaxMapSessions + 1;
  EXPECT_THROW(o.check(), Error);
  o.map_sessions = 3;
  o.map_frames = 2;
  EXPECT_THROW(o.check(), Error);
  o.map_frames = 30;
  o.query_sessions = 0;
  EXPECT_THROW(o.check(), Error);
}

TEST(TrajectoryTest, CameraIsTheDocumentedOpenCvModel) {
  const Camera c = world_camera();
  EXPECT_EQ(c.model, CameraModel::kOpenCV);
  EXPECT_EQ(c.width, 640);
  EXPECT_EQ(c.height, 480);
  EXPECT_TRUE(c.has_distortion());
  EXPECT_NO_THROW(c.check());
}

}  // namespace
}  // namespace lmb
