// A tiny application using the installed LandmarkBoost inference library. Each check_* function
// exercises one public API and returns the number of failures; main returns nonzero when any
// check fails. Later APIs (the localizer, the C API) get their own check_* function here.
#include <cmath>
#include <cstdio>
#include <vector>

#include "common/camera.h"
#include "common/error.h"
#include "common/random.h"
#include "infer/pose_estimator.h"

namespace {

int failures = 0;

void expect(bool ok, const char* what) {
  std::printf("%s: %s\n", ok ? "ok  " : "FAIL", what);
  if (!ok) ++failures;
}

lmb::Camera make_camera() {
  lmb::Camera camera;
  camera.model = lmb::CameraModel::kSimpleRadial;
  camera.width = 640;
  camera.height = 480;
  camera.params = {500.0, 320.0, 240.0, -0.1};
  camera.check();  // from the installed static LandmarkBoost::common
  return camera;
}

// 100 points seen by a known camera, 30 of them with a wrong pixel; returns the true pose.
lmb::Rigid3d make_problem(const lmb::Camera& camera, std::vector<Eigen::Vector2d>* pixels,
                          std::vector<Eigen::Vector3d>* points_world) {
  lmb::Rng rng(2024);
  const lmb::Rigid3d cam_from_world(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized())),
      Eigen::Vector3d(0.5, -1.0, 2.0));
  const lmb::Rigid3d world_from_cam = cam_from_world.inverse();
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector2d pixel(rng.uniform(0, camera.width), rng.uniform(0, camera.height));
    const double depth = rng.uniform(2.0, 10.0);
    points_world->push_back(world_from_cam * (depth * camera.cam_from_img(pixel).homogeneous()));
    pixels->push_back(i < 30 ? Eigen::Vector2d(rng.uniform(0, camera.width),
                                               rng.uniform(0, camera.height))
                             : pixel);
  }
  return cam_from_world;
}

void check_pose_api() {
  const lmb::Camera camera = make_camera();
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points_world;
  const lmb::Rigid3d truth = make_problem(camera, &pixels, &points_world);

  lmb::PoseEstimatorOptions options;
  options.seed = 7;
  const lmb::PoseResult result = lmb::estimate_absolute_pose(camera, pixels, points_world, options);
  expect(result.success, "estimate_absolute_pose succeeds");
  expect(lmb::position_error(result.cam_from_world, truth) < 1e-3, "position within 1 mm");
  expect(lmb::rotation_error_deg(result.cam_from_world, truth) < 0.01, "rotation within 0.01 deg");
  expect(result.num_inliers >= 70 && result.num_inliers <= 72, "70 inliers (+ chance outliers)");
  std::printf("      position error %.2e m, %d inliers, %d iterations\n",
              lmb::position_error(result.cam_from_world, truth), result.num_inliers,
              result.iterations);

  // An lmb::Error thrown inside liblmb_infer.so is caught here by type.
  bool caught = false;
  try {
    points_world.pop_back();
    lmb::estimate_absolute_pose(camera, pixels, points_world, options);
  } catch (const lmb::Error& e) {
    caught = true;
    std::printf("      caught lmb::Error: %s\n", e.what());
  }
  expect(caught, "lmb::Error crosses the library boundary");
}

}  // namespace

int main() {
  check_pose_api();
  std::printf("%s\n", failures == 0 ? "consumer: all checks passed" : "consumer: FAILED");
  return failures == 0 ? 0 : 1;
}
