#include "train/mapping/frame_pairs.h"

#include <algorithm>
#include <cmath>

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

// A dense video: 200 map frames 1.5 cm apart along x, looking at a wall (y = 3, points on a grid),
// then 20 map frames looking the other way at another wall (y = -3). A query frame stands 1 m
// behind the path and looks at the first wall.
struct WallScene {
  Camera camera;
  std::vector<PairFrame> frames;
  ScenePoints scene;
  int query = 0;
};

WallScene wall_scene() {
  WallScene w;
  w.camera.model = CameraModel::kPinhole;
  w.camera.width = 640;
  w.camera.height = 480;
  w.camera.params = {500, 500, 320, 240};
  for (int i = 0; i < 200; ++i) {
    w.frames.push_back({test::look_along(Eigen::Vector3d(0.015 * i, 0, 1.5), M_PI / 2), false, 0, false, &w.camera});
  }
  for (int i = 0; i < 20; ++i) {
    w.frames.push_back({test::look_along(Eigen::Vector3d(0.15 * i, 0.5, 1.5), -M_PI / 2), false, 0, false, &w.camera});
  }
  w.query = static_cast<int>(w.frames.size());
  w.frames.push_back({test::look_along(Eigen::Vector3d(1.5, -1.0, 1.5), M_PI / 2), true, 1, false, &w.camera});
  for (double y : {3.0, -3.0}) {
    for (double x = -2.0; x <= 5.0; x += 0.1) {
      for (double z = 0.2; z <= 2.8; z += 0.2) {
        std::vector<int> observers;
        for (int j = 0; j < w.query; ++j) {
          const Eigen::Vector3d p = w.frames[j].cam_from_world * Eigen::Vector3d(x, y, z);
          Eigen::Vector2d pixel;
          if (p.z() > 0.2 && w.camera.project(p, &pixel) && pixel.x() >= 0 && pixel.x() <= 640 && pixel.y() >= 0 &&
              pixel.y() <= 480)
            observers.push_back(j);
        }
        if (observers.size() < 3) continue;
        w.scene.position.emplace_back(x, y, z);
        w.scene.observers.push_back(observers);
      }
    }
  }
  return w;
}

// Shared points of the query and map frame j by the rule select_overlap_pairs states (brute force).
int shared_points(const WallScene& w, int j, const OverlapPairOptions& o) {
  int shared = 0;
  const Eigen::Vector3d ci = w.frames[w.query].cam_from_world.center(), cj = w.frames[j].cam_from_world.center();
  for (size_t p = 0; p < w.scene.position.size(); ++p) {
    const Eigen::Vector3d x = w.frames[w.query].cam_from_world * w.scene.position[p];
    Eigen::Vector2d pixel;
    if (x.z() < o.min_depth || x.z() > o.max_depth || !w.camera.project(x, &pixel)) continue;
    if (pixel.x() < 0 || pixel.x() > 640 || pixel.y() < 0 || pixel.y() > 480) continue;
    if (!std::binary_search(w.scene.observers[p].begin(), w.scene.observers[p].end(), j)) continue;
    const Eigen::Vector3d a = w.scene.position[p] - ci, b = w.scene.position[p] - cj;
    if (a.normalized().dot(b.normalized()) < std::cos(o.max_ray_angle_deg * M_PI / 180)) continue;
    if (a.norm() > o.max_scale_change * b.norm() || b.norm() > o.max_scale_change * a.norm()) continue;
    ++shared;
  }
  return shared;
}

TEST(SelectOverlapPairs, LinksAQueryToMapFramesSeeingItsSceneFromAMetreAway) {
  const WallScene w = wall_scene();
  // The pose rule's automatic distance (8 x 1.5 cm) leaves the query without a partner.
  PairOptions by_pose;
  for (const auto& [i, j] : select_frame_pairs(w.frames, by_pose)) EXPECT_NE(j, w.query) << i;

  OverlapPairOptions o;
  OverlapPairStats stats;
  const auto pairs = select_overlap_pairs(w.frames, w.scene, o, &stats);
  ASSERT_GE(pairs.size(), 8u);  // up to K: partners 4 deg apart along the 3 m path
  ASSERT_LE(static_cast<int>(pairs.size()), o.partners_per_frame);
  EXPECT_EQ(stats.query_frames_with, 1);
  EXPECT_EQ(stats.query_frames_without, 0);
  EXPECT_GE(stats.median_partner_distance, 1.0);
  EXPECT_LT(stats.max_partner_distance, 2.0);
  // The partners look at the query's wall, include the map frame sharing most points with it, and
  // are spread out: pairwise at least the minimum view change apart (here all look the same way,
  // so centre distance / scene depth), which spans more than a metre of the path.
  int best = -1, best_shared = -1;
  for (int j = 0; j < w.query; ++j) {
    const int n = shared_points(w, j, o);
    if (n > best_shared) best = j, best_shared = n;
  }
  EXPECT_TRUE(has(pairs, best, w.query)) << best;
  double min_x = 1e9, max_x = -1e9;
  for (const auto& [i, j] : pairs) {
    EXPECT_EQ(j, w.query);
    EXPECT_LT(i, 200) << "a map frame looking away";
    EXPECT_GE(shared_points(w, i, o), o.min_shared_points);
    min_x = std::min(min_x, w.frames[i].cam_from_world.center().x());
    max_x = std::max(max_x, w.frames[i].cam_from_world.center().x());
    for (const auto& [k, l] : pairs) {
      if (k >= i) continue;
      const double apart = (w.frames[i].cam_from_world.center() - w.frames[k].cam_from_world.center()).norm();
      EXPECT_GE(apart / 4.0 * 180 / M_PI, o.min_partner_separation_deg * 0.99) << i << "," << k;  // depth 4 m
    }
  }
  EXPECT_GT(max_x - min_x, 1.0);
  // Without the spread, the partners are the K frames sharing most points: near-duplicates.
  o.min_partner_separation_deg = 0;
  const auto crowded = select_overlap_pairs(w.frames, w.scene, o);
  double crowded_min = 1e9, crowded_max = -1e9;
  for (const auto& [i, j] : crowded) {
    crowded_min = std::min(crowded_min, w.frames[i].cam_from_world.center().x());
    crowded_max = std::max(crowded_max, w.frames[i].cam_from_world.center().x());
  }
  EXPECT_LT(crowded_max - crowded_min, 0.5);
}

// Map frames get no overlap partners, outside frames none; observers must be map frames.
TEST(SelectOverlapPairs, OnlyQueryFramesAndChecks) {
  WallScene w = wall_scene();
  w.frames[w.query].outside = true;
  EXPECT_TRUE(select_overlap_pairs(w.frames, w.scene, {}).empty());
  w.frames[w.query].outside = false;
  w.frames[5].is_query = true;  // observes points: not allowed
  EXPECT_THROW(select_overlap_pairs(w.frames, w.scene, {}), Error);
  OverlapPairOptions bad;
  bad.max_scale_change = 0.5;
  EXPECT_THROW(select_overlap_pairs({}, {}, bad), Error);
}

TEST(SelectFramePairs, BadOptionsThrow) {
  PairOptions options;
  options.max_view_angle_deg = 0;
  EXPECT_THROW(select_frame_pairs({}, options), Error);
}

}  // namespace
}  // namespace lmb
