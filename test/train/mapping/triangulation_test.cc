#include "train/mapping/triangulation.h"

#include <gtest/gtest.h>

#include "common/random.h"
#include "synthetic_scene.h"

namespace lmb {
namespace {

Camera test_camera() {
  Camera c;
  c.model = CameraModel::kOpenCV;
  c.width = 640;
  c.height = 480;
  c.params = {500, 505, 320, 240, -0.1, 0.02, 0.001, -0.001};
  return c;
}

std::vector<TrackObservation> observe(const Camera& camera, const Eigen::Vector3d& point, int n, double noise, Rng& rng,
                                      double spacing = 0.3) {
  std::vector<TrackObservation> obs;
  for (int i = 0; i < n; ++i) {
    const Rigid3d pose = test::look_along(Eigen::Vector3d(spacing * i, 0.1 * i, 1.5), 0.05 * i);
    Eigen::Vector2d px;
    EXPECT_TRUE(camera.project(pose * point, &px));
    px += Eigen::Vector2d(rng.normal(), rng.normal()) * noise;
    obs.push_back(TrackObservation{&camera, pose, px});
  }
  return obs;
}

TEST(TriangulateTrack, ExactWithoutNoise) {
  const Camera camera = test_camera();
  Rng rng(1);
  const Eigen::Vector3d point(6.0, 0.7, 1.1);
  const auto obs = observe(camera, point, 5, 0.0, rng);
  const TriangulatedPoint t = triangulate_track(obs, TriangulationOptions{});
  ASSERT_TRUE(t.success);
  EXPECT_LT((t.position - point).norm(), 1e-6);
  EXPECT_EQ(t.num_inliers, 5);
  EXPECT_LT(t.mean_reprojection_error_px, 1e-4);
  EXPECT_GT(t.triangulation_angle_deg, 2.0);
}

TEST(TriangulateTrack, RejectsOutliersAndRefines) {
  const Camera camera = test_camera();
  Rng rng(2);
  double error_sum = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d point(rng.uniform(4, 8), rng.uniform(-1.5, 1.5), rng.uniform(0.5, 2.5));
    auto obs = observe(camera, point, 8, 0.5, rng);
    obs[3].pixel += Eigen::Vector2d(25, -18);  // a wrong match
    const TriangulatedPoint t = triangulate_track(obs, TriangulationOptions{});
    ASSERT_TRUE(t.success);
    EXPECT_FALSE(t.inlier[3]);
    EXPECT_EQ(t.num_inliers, 7);
    EXPECT_LT(t.mean_reprojection_error_px, 1.5);
    error_sum += (t.position - point).norm();
  }
  EXPECT_LT(error_sum / 20, 0.05);  // 0.5 px noise at 4-8 m depth, 2.1 m baseline
}

TEST(TriangulateTrack, FailsOnTooSmallAngleOrBehindCamera) {
  const Camera camera = test_camera();
  Rng rng(3);
  const Eigen::Vector3d far_point(40.0, 0.5, 1.5);
  const auto obs = observe(camera, far_point, 3, 0.0, rng, 0.01);
  TriangulationOptions options;
  options.min_triangulation_angle_deg = 2.0;
  EXPECT_FALSE(triangulate_track(obs, options).success);
  // Two observations of unrelated points: no hypothesis has both in front with small error.
  auto a = observe(camera, Eigen::Vector3d(6, 1, 1), 1, 0.0, rng);
  auto b = observe(camera, Eigen::Vector3d(6, -1, 2), 2, 0.0, rng);
  std::vector<TrackObservation> mixed = {a[0], b[1]};
  mixed[1].pixel = Eigen::Vector2d(600, 20);
  const TriangulatedPoint t = triangulate_track(mixed, options);
  if (t.success) {
    EXPECT_LT(reprojection_error_px(mixed[0], t.position), options.max_reprojection_error_px);
    EXPECT_LT(reprojection_error_px(mixed[1], t.position), options.max_reprojection_error_px);
  }
  EXPECT_FALSE(triangulate_track({a[0]}, options).success);
}

TEST(TriangulateTrack, ReprojectionErrorBehindCameraIsInfinite) {
  const Camera camera = test_camera();
  const TrackObservation o{&camera, Rigid3d(), Eigen::Vector2d(320, 240)};
  EXPECT_TRUE(std::isinf(reprojection_error_px(o, Eigen::Vector3d(0, 0, -5))));
  EXPECT_NEAR(reprojection_error_px(o, Eigen::Vector3d(0, 0, 5)), 0.0, 1e-9);
}

}  // namespace
}  // namespace lmb
