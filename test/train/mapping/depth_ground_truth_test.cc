#include "train/mapping/depth_ground_truth.h"

#include <unistd.h>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

// Two frames facing a wall at z = 4 m (world = camera 0 frame), camera 1 shifted 0.5 m right.
LandmarkMap wall_map() {
  LandmarkMap map;
  map.descriptor_bytes = 32;
  Camera c;
  c.model = CameraModel::kPinhole;
  c.width = 200;
  c.height = 100;
  c.params = {100, 100, 100, 50};
  map.cameras = {c};
  for (int f = 0; f < 2; ++f) {
    MapFrame frame;
    frame.name = "map/" + std::to_string(f) + ".png";
    frame.cam_from_world.translation = Eigen::Vector3d(-0.5 * f, 0, 0);
    frame.first_keypoint = 3 * f;
    frame.num_keypoints = 3;
    map.frames.push_back(frame);
  }
  // World points on the wall; keypoint k of each frame observes point k (the last one of frame 1
  // is placed on point 0's pixel by mistake: a wrong observation).
  const Eigen::Vector3d points[3] = {{0.2, 0.1, 4}, {-1.0, -0.3, 4}, {0.8, 0.6, 4}};
  for (int f = 0; f < 2; ++f) {
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector2d px;
      const Eigen::Vector3d p = points[(f == 1 && k == 2) ? 0 : k];
      c.project(map.frames[f].cam_from_world * p, &px);
      map.keypoints.push_back(Keypoint{static_cast<float>(px.x()), static_cast<float>(px.y()), 10, -1});
    }
  }
  map.descriptors.assign(6 * 32, 0);
  map.keypoint_landmark = {0, 1, 2, 0, 1, 2};
  map.landmarks.resize(3);
  for (int l = 0; l < 3; ++l) {
    map.landmarks[l].position = points[l] + Eigen::Vector3d(0.01 * l, 0, 0);
    map.landmarks[l].num_map_observations = 2;
  }
  return map;
}

TEST(DepthGroundTruth, BackProjectsWithZDepth) {
  const LandmarkMap map = wall_map();
  std::vector<uint16_t> depth(200 * 100, 4000);
  depth[0] = 0;  // no depth at the top-left pixel
  const auto pts = back_project_keypoints(map, 1, depth.data(), 200, 100);
  ASSERT_EQ(pts.size(), 3u);
  EXPECT_LT((pts[0] - Eigen::Vector3d(0.2, 0.1, 4)).norm(), 1e-5);
  EXPECT_LT((pts[1] - Eigen::Vector3d(-1.0, -0.3, 4)).norm(), 1e-5);
}

TEST(DepthGroundTruth, PurityAndPositionErrorKnownAnswer) {
  const fs::path dir = fs::temp_directory_path() / ("lmb_depth_gt_" + std::to_string(::getpid()));
  fs::create_directories(dir / "depth" / "map");
  const cv::Mat depth(100, 200, CV_16UC1, cv::Scalar(4000));
  for (int f = 0; f < 2; ++f) cv::imwrite((dir / "depth" / "map" / (std::to_string(f) + ".png")).string(), depth);
  const MapAccuracy a = check_map_against_depth(wall_map(), dir);
  EXPECT_EQ(a.landmarks_checked, 3);
  EXPECT_EQ(a.observations_checked, 6);
  // Landmark 2 has one right and one wrong observation: the tie goes to the first (right) one.
  EXPECT_NEAR(a.mean_track_purity, (1.0 + 1.0 + 0.5) / 3, 1e-9);
  EXPECT_NEAR(a.observation_purity, 5.0 / 6, 1e-9);
  EXPECT_NEAR(a.pure_track_share, 2.0 / 3, 1e-9);
  EXPECT_NEAR(a.median_position_error_m, 0.01, 1e-6);
  fs::remove(dir / "depth" / "map" / "1.png");
  EXPECT_THROW(check_map_against_depth(wall_map(), dir), Error);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lmb
