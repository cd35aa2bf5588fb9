#include "train/mapping/frame_pairs.h"

#include <algorithm>

#include <gtest/gtest.h>

#include "common/error.h"
#include "synthetic_scene.h"

namespace lmb {
namespace {

bool has(const std::vector<std::pair<int, int>>& pairs, int i, int j) {
  return std::binary_search(pairs.begin(), pairs.end(), std::make_pair(std::min(i, j), std::max(i, j)));
}

TEST(SelectFramePairs, DistanceAngleAndSequence) {
  std::vector<PairFrame> frames;
  for (int i = 0; i < 10; ++i) frames.push_back({test::look_along(Eigen::Vector3d(i, 0, 1), 0.0), false});
  frames.push_back({test::look_along(Eigen::Vector3d(2.2, 0, 1), M_PI), false});  // 10: looks backwards
  frames.push_back({test::look_along(Eigen::Vector3d(3.1, 0, 1), 0.1), true});    // 11: query
  frames.push_back({test::look_along(Eigen::Vector3d(3.2, 0, 1), 0.1), true});    // 12: query
  PairOptions options;
  options.max_center_distance = 2.5;
  options.max_view_angle_deg = 60;
  options.sequence_neighbors = 0;
  options.max_pairs_per_frame = 100;
  const auto pairs = select_frame_pairs(frames, options);
  EXPECT_TRUE(std::is_sorted(pairs.begin(), pairs.end()));
  // Brute-force reference of the distance and angle rule.
  for (int i = 0; i < 13; ++i) {
    for (int j = i + 1; j < 13; ++j) {
      const double d = (frames[i].cam_from_world.center() - frames[j].cam_from_world.center()).norm();
      const bool same_dir = (i == 10) == (j == 10);
      const bool both_query = frames[i].is_query && frames[j].is_query;
      EXPECT_EQ(has(pairs, i, j), d <= 2.5 && same_dir && !both_query) << i << "," << j;
    }
  }
  // Sequence neighbours join map frames beyond the distance limit, never queries.
  options.sequence_neighbors = 4;
  options.max_center_distance = 0.5;
  const auto seq = select_frame_pairs(frames, options);
  EXPECT_TRUE(has(seq, 0, 4));
  EXPECT_FALSE(has(seq, 0, 5));
  EXPECT_TRUE(has(seq, 9, 10));
  EXPECT_FALSE(has(seq, 11, 12));
}

// Sequence neighbours stay within a session; outside frames are never paired.
TEST(SelectFramePairs, SessionsAndOutsideFrames) {
  std::vector<PairFrame> frames;
  for (int i = 0; i < 4; ++i) frames.push_back({test::look_along(Eigen::Vector3d(10.0 * i, 0, 1), 0.0), false, 0});
  for (int i = 0; i < 4; ++i) frames.push_back({test::look_along(Eigen::Vector3d(10.0 * i + 5, 0, 1), 0.0), false, 1});
  frames.push_back({test::look_along(Eigen::Vector3d(0.1, 0, 1), 0.0), true, 2, true});  // 8: outside, beside frame 0
  frames.push_back({test::look_along(Eigen::Vector3d(0.2, 0, 1), 0.0), true, 3});        // 9: query, beside frame 0
  PairOptions options;
  options.max_center_distance = 1.0;
  options.sequence_neighbors = 2;
  const auto pairs = select_frame_pairs(frames, options);
  EXPECT_TRUE(has(pairs, 0, 1));
  EXPECT_TRUE(has(pairs, 0, 2));
  EXPECT_TRUE(has(pairs, 2, 3));
  EXPECT_TRUE(has(pairs, 4, 5));
  EXPECT_TRUE(has(pairs, 0, 9));
  EXPECT_FALSE(has(pairs, 3, 4));  // consecutive in the list, but in other sessions
  for (const auto& [i, j] : pairs) {
    EXPECT_NE(i, 8);
    EXPECT_NE(j, 8);
    EXPECT_EQ(frames[i].session == frames[j].session || i == 0, true) << i << "," << j;
  }
}

TEST(SelectFramePairs, CapPerFrameKeepsClosest) {
  std::vector<PairFrame> frames;
  for (int i = 0; i < 20; ++i) frames.push_back({test::look_along(Eigen::Vector3d(0.1 * i, 0, 1), 0.0), false});
  PairOptions options;
  options.max_center_distance = 100;
  options.max_pairs_per_frame = 2;
  options.sequence_neighbors = 0;
  const auto pairs = select_frame_pairs(frames, options);
  EXPECT_TRUE(has(pairs, 5, 6));
  EXPECT_TRUE(has(pairs, 5, 4));
  EXPECT_FALSE(has(pairs, 5, 8));
  EXPECT_LE(pairs.size(), 40u);
}

TEST(SelectFramePairs, AutomaticDistance) {
  std::vector<PairFrame> frames;
  for (int i = 0; i < 10; ++i) frames.push_back({test::look_along(Eigen::Vector3d(0.5 * i, 0, 1), 0.0), false});
  EXPECT_NEAR(automatic_pair_distance(frames), 8 * 0.5, 1e-9);
  EXPECT_EQ(automatic_pair_distance({frames[0]}), 0.0);
}

TEST(SelectFramePairs, BadOptionsThrow) {
  PairOptions options;
  options.max_view_angle_deg = 0;
  EXPECT_THROW(select_frame_pairs({}, options), Error);
}

}  // namespace
}  // namespace lmb
