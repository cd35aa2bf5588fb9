#include "train/world/landmark_stats.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include "common/error.h"
#include "train/world/world_writer.h"

namespace fs = std::filesystem;

namespace lmb {
namespace {

TEST(LandmarkStatsTest, DenseFramesOfOneWorldShareLandmarks) {
  const fs::path dir = fs::temp_directory_path() / ("lmb_landmark_stats_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  WorldOptions o = world_preset("tiny");
  o.length_m = 4.0;  // the walks cover 1 m: consecutive frames overlap strongly
  o.map_frames = 8;
  o.query_frames = 2;
  write_world(o, dir);
  const LandmarkStats s = estimate_landmarks(dir);
  EXPECT_EQ(s.map_frames, 8);
  EXPECT_EQ(s.query_frames, 2);
  EXPECT_GT(s.map_keypoints, 8 * 100);
  EXPECT_LE(s.landmarks_10, s.landmarks_3);
  EXPECT_LE(s.landmarks_3, s.points);
  EXPECT_LE(s.points, s.map_keypoints);
  // Exact depth and poses make the same surface points meet in one voxel across frames.
  EXPECT_GT(s.landmarks_3, 100);
  EXPECT_GT(s.query_on_landmark, 0);
  EXPECT_LE(s.query_on_landmark, s.query_keypoints);
  // A larger merge radius merges more keypoints into fewer points.
  EXPECT_LT(estimate_landmarks(dir, 0.05).points, s.points);
  fs::remove_all(dir / "depth" / "map" / "000003.png");
  EXPECT_THROW(estimate_landmarks(dir), Error);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lmb
