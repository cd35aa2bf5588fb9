#include "train/world/trajectory.h"

#include <cmath>

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
