// The minimal solver (infer/p3p.h): the true pose is among its solutions on exact minimal
// samples, and its solutions are OpenGV's P3P (Kneip) on the same samples, converted from
// world_from_cam to cam_from_world.
#include "infer/p3p.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <opengv/absolute_pose/CentralAbsoluteAdapter.hpp>
#include <opengv/absolute_pose/methods.hpp>

#include "common/random.h"

namespace lmb {
namespace {

struct Sample {
  CameraPose truth;
  Eigen::Vector3d bearings[3];
  Eigen::Vector3d points[3];
};

// A random camera and three random points 2..12 m in front of it, inside a 90-degree cone.
Sample random_sample(Rng& rng) {
  Sample s;
  const Eigen::Vector3d axis(rng.normal(), rng.normal(), rng.normal());
  s.truth.rotation = Eigen::AngleAxisd(rng.uniform(0, M_PI), axis.normalized()).toRotationMatrix();
  s.truth.translation = Eigen::Vector3d(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-5, 5));
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d cam(rng.uniform(-1, 1), rng.uniform(-1, 1), 1.0);
    const Eigen::Vector3d x = cam.normalized() * rng.uniform(2, 12);
    s.bearings[k] = x.normalized();
    s.points[k] = s.truth.rotation.transpose() * (x - s.truth.translation);
  }
  return s;
}

double pose_distance(const CameraPose& a, const CameraPose& b) {
  return (a.rotation - b.rotation).norm() + (a.translation - b.translation).norm();
}

TEST(P3p, TheTruePoseIsAmongTheSolutions) {
  Rng rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    const Sample s = random_sample(rng);
    std::vector<CameraPose> solutions;
    const int added = p3p(s.bearings, s.points, &solutions);
    ASSERT_EQ(added, static_cast<int>(solutions.size()));
    ASSERT_GE(added, 1) << "trial " << trial;
    ASSERT_LE(added, 4);
    double best = INFINITY;
    for (const CameraPose& p : solutions) {
      best = std::min(best, pose_distance(p, s.truth));
      EXPECT_NEAR((p.rotation.transpose() * p.rotation - Eigen::Matrix3d::Identity()).norm(), 0, 1e-9);
    }
    EXPECT_LT(best, 1e-6) << "trial " << trial;
    // The true pose explains the three correspondences (the other candidates need not: Kneip's
    // quartic gives the real parts of its roots and lines, not rays).
  }
}

TEST(P3p, EqualsOpenGvKneipOnTheSameSamples) {
  Rng rng(11);
  for (int trial = 0; trial < 200; ++trial) {
    const Sample s = random_sample(rng);
    std::vector<CameraPose> ours;
    p3p(s.bearings, s.points, &ours);
    opengv::bearingVectors_t b(s.bearings, s.bearings + 3);
    opengv::points_t pts(s.points, s.points + 3);
    opengv::absolute_pose::CentralAbsoluteAdapter adapter(b, pts);
    const opengv::transformations_t theirs = opengv::absolute_pose::p3p_kneip(adapter, 0, 1, 2);
    size_t k = 0;
    for (const opengv::transformation_t& T : theirs) {
      if (!T.allFinite()) continue;
      ASSERT_LT(k, ours.size()) << "trial " << trial;
      const Eigen::Matrix3d R = T.leftCols<3>().transpose();
      EXPECT_TRUE(ours[k].rotation == R) << "trial " << trial << " solution " << k;
      EXPECT_TRUE(ours[k].translation == -(R * T.col(3))) << "trial " << trial << " solution " << k;
      EXPECT_TRUE(ours[k].center().isApprox(T.col(3), 1e-12)) << "trial " << trial;
      ++k;
    }
    EXPECT_EQ(k, ours.size()) << "trial " << trial;
  }
}

TEST(P3p, DegenerateSamplesGiveNoFalseNumbers) {
  // Collinear points and a repeated correspondence: no throw, only finite poses, appended after
  // what the vector held.
  Eigen::Vector3d points[3] = {{0, 0, 5}, {1, 0, 5}, {2, 0, 5}};
  Eigen::Vector3d bearings[3];
  for (int k = 0; k < 3; ++k) bearings[k] = points[k].normalized();
  std::vector<CameraPose> solutions(1);
  const int added = p3p(bearings, points, &solutions);
  EXPECT_EQ(solutions.size(), 1u + added);
  for (const CameraPose& p : solutions) {
    EXPECT_TRUE(p.rotation.allFinite() && p.translation.allFinite());
  }
  points[2] = points[1];
  bearings[2] = bearings[1];
  solutions.clear();
  p3p(bearings, points, &solutions);
  for (const CameraPose& p : solutions) EXPECT_TRUE(p.rotation.allFinite() && p.translation.allFinite());
}

}  // namespace
}  // namespace lmb
