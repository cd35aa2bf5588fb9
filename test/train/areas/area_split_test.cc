#include "train/areas/area_split.h"

#include <algorithm>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/random.h"
#include "test/train/areas/area_test_map.h"

namespace lmb {
namespace {

// Brute force: landmarks with >= n observations in map frames.
std::set<landmark_t> eligible(const LandmarkMap& map, int n) {
  std::vector<int> count(map.landmarks.size(), 0);
  for (const MapFrame& f : map.frames) {
    if (f.is_query) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      if (map.keypoint_landmark[k] >= 0) ++count[map.keypoint_landmark[k]];
    }
  }
  std::set<landmark_t> out;
  for (size_t l = 0; l < count.size(); ++l) {
    if (count[l] >= n) out.insert(static_cast<landmark_t>(l));
  }
  return out;
}

TEST(AreaSplit, CoversEveryEligibleLandmarkAndRespectsK) {
  const LandmarkMap map = test::corridor_map();
  AreaSplitOptions options;
  options.max_classes = 100;
  options.min_observations = 5;
  options.overlap = 0.5;
  const AreaSplit split = split_map_into_areas(map, options);
  const std::set<landmark_t> want = eligible(map, 5);
  ASSERT_GT(want.size(), 300u);
  ASSERT_LT(want.size(), map.landmarks.size());  // the first landmarks have too few observations
  EXPECT_EQ(split.num_eligible, static_cast<int64_t>(want.size()));
  ASSERT_GE(split.areas.size(), 4u);
  std::set<landmark_t> covered;
  for (size_t i = 0; i < split.areas.size(); ++i) {
    const Area& a = split.areas[i];
    EXPECT_EQ(a.id, static_cast<int32_t>(i));
    EXPECT_LE(a.landmarks.size(), 100u);
    EXPECT_GT(a.landmarks.size(), 50u);  // split into as many parts as needed, not halved blindly
    EXPECT_EQ(a.num_truncated, 0);
    EXPECT_TRUE(std::is_sorted(a.landmarks.begin(), a.landmarks.end()));
    int64_t core = 0;
    for (landmark_t l : a.landmarks) {
      EXPECT_TRUE(want.count(l)) << "area " << i << " holds ineligible landmark " << l;
      const double d = a.cell.distance(map.landmarks[l].position);
      EXPECT_LE(d, 0.5) << "area " << i << " landmark " << l;
      core += d == 0.0;
      covered.insert(l);
    }
    EXPECT_EQ(core, a.num_core);
  }
  EXPECT_EQ(covered, want);
  // Brute force: every eligible landmark lies in one cell, is in that cell's area, and is in the
  // area of every cell within `overlap` of it.
  for (landmark_t l : want) {
    const Eigen::Vector3d& p = map.landmarks[l].position;
    int inside = 0;
    for (const Area& a : split.areas) {
      const bool holds = std::binary_search(a.landmarks.begin(), a.landmarks.end(), l);
      inside += a.cell.distance(p) == 0.0;
      EXPECT_EQ(holds, a.cell.distance(p) <= 0.5) << "landmark " << l << " area " << a.id;
    }
    EXPECT_EQ(inside, 1) << "landmark " << l;
  }
  EXPECT_TRUE(uncovered_landmarks(map, split).empty());
  EXPECT_EQ(split.options.reach, map_observation_distance(map, 0.9));
}

TEST(AreaSplit, ReachIsTheQuantileOfMapObservationDistances) {
  const LandmarkMap map = test::corridor_map();
  std::vector<double> d;
  for (const MapFrame& f : map.frames) {
    if (f.is_query) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      if (map.keypoint_landmark[k] >= 0) {
        d.push_back((map.landmarks[map.keypoint_landmark[k]].position - f.cam_from_world.center()).norm());
      }
    }
  }
  std::sort(d.begin(), d.end());
  for (double q : {0.0, 0.5, 0.9}) {
    EXPECT_EQ(map_observation_distance(map, q), d[static_cast<size_t>(q * static_cast<double>(d.size()))]) << q;
  }
  EXPECT_EQ(map_observation_distance(map, 1.0), d.back());
  AreaSplitOptions options;
  options.reach = 2.5;  // given: kept
  EXPECT_EQ(split_map_into_areas(map, options).options.reach, 2.5);
}

TEST(AreaSplit, IsDeterministic) {
  const LandmarkMap map = test::corridor_map();
  AreaSplitOptions options;
  options.max_classes = 120;
  const AreaSplit a = split_map_into_areas(map, options);
  // The same map with its frames listed in reverse order of position gives the same areas (ties
  // and splits depend on positions and ids only through a total order).
  LandmarkMap reversed = map;
  std::reverse(reversed.frames.begin(), reversed.frames.end());
  const AreaSplit b = split_map_into_areas(reversed, options);
  const AreaSplit c = split_map_into_areas(map, options);
  ASSERT_GE(a.areas.size(), 3u);
  ASSERT_EQ(a.areas.size(), c.areas.size());
  for (size_t i = 0; i < a.areas.size(); ++i) EXPECT_EQ(a.areas[i].landmarks, c.areas[i].landmarks);
  ASSERT_EQ(a.areas.size(), b.areas.size());
  for (size_t i = 0; i < a.areas.size(); ++i) {
    EXPECT_EQ(a.areas[i].landmarks, b.areas[i].landmarks);
    EXPECT_EQ(a.areas[i].cell.lo, b.areas[i].cell.lo);
    EXPECT_EQ(a.areas[i].cell.hi, b.areas[i].cell.hi);
  }
}

TEST(AreaSplit, CellsPartitionSpaceAndAreasNearMatchesBruteForce) {
  const LandmarkMap map = test::corridor_map();
  AreaSplitOptions options;
  options.max_classes = 80;
  const AreaSplit split = split_map_into_areas(map, options);
  Rng rng(7);
  for (int trial = 0; trial < 2000; ++trial) {
    const Eigen::Vector3d p(rng.uniform(-10, 50), rng.uniform(-5, 5), rng.uniform(-5, 5));
    // Exactly one cell contains p (the splits are at half-way points that random draws miss).
    EXPECT_EQ(areas_near(split, p, 0.0).size(), 1u) << p.transpose();
    const double r = rng.uniform(0, 6);
    const std::vector<int32_t> near = areas_near(split, p, r);
    // Brute force: an area is near iff some point of its cell is within r; sample the ball.
    for (int s = 0; s < 20; ++s) {
      const Eigen::Vector3d q = p + rng.uniform(0, r) * prior_direction(trial, s);
      const std::vector<int32_t> inside = areas_near(split, q, 0.0);
      ASSERT_EQ(inside.size(), 1u);
      EXPECT_TRUE(std::binary_search(near.begin(), near.end(), inside[0]));
    }
    for (int32_t id : near) {
      const AreaBox& c = split.areas[id].cell;
      const Eigen::Vector3d closest = p.cwiseMax(c.lo).cwiseMin(c.hi);
      EXPECT_LE((closest - p).norm(), r + 1e-12);
    }
  }
}

TEST(AreaSplit, PriorSelectsTheAreasHoldingWhatTheCameraSees) {
  const LandmarkMap map = test::corridor_map();
  AreaSplitOptions options;
  options.max_classes = 100;
  options.overlap = 0.5;
  options.reach = 4.0;  // a camera sees [cx - 1, cx + 4) along the corridor, all within 4 m
  const AreaSplit split = split_map_into_areas(map, options);
  const std::set<landmark_t> want = eligible(map, 5);
  int64_t eligible_query = 0;
  for (const MapFrame& f : map.frames) {
    if (!f.is_query) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      eligible_query += map.keypoint_landmark[k] >= 0 && want.count(map.keypoint_landmark[k]);
    }
  }
  for (double noise : {0.0, 3.0}) {
    const AreaCoverage c = query_coverage(map, split, noise);
    EXPECT_EQ(c.num_query_frames, 52);
    EXPECT_EQ(c.num_keypoints, 52 * 50);
    EXPECT_EQ(c.num_eligible, eligible_query);
    EXPECT_EQ(c.num_covered_any, eligible_query) << noise;  // everything within reach is selected
    EXPECT_LT(c.num_covered_best, c.num_covered_any);       // no area holds a whole view
    EXPECT_GT(c.mean_selected_areas, 1.0);
    EXPECT_LT(c.mean_selected_areas, static_cast<double>(split.areas.size()));
  }
  EXPECT_GT(query_coverage(map, split, 3.0).mean_selected_areas, query_coverage(map, split, 0.0).mean_selected_areas);
  // A short reach selects fewer areas and misses landmarks.
  options.reach = 0.5;
  const AreaCoverage short_reach = query_coverage(map, split_map_into_areas(map, options), 0.0);
  EXPECT_LT(short_reach.num_covered_any, eligible_query);
  // Overlap puts more of a view into its best area.
  options.reach = 4.0;
  options.overlap = 0.0;
  const AreaCoverage no_overlap = query_coverage(map, split_map_into_areas(map, options), 0.0);
  options.overlap = 1.0;
  options.max_classes = 150;
  const AreaSplit wide = split_map_into_areas(map, options);
  options.overlap = 0.0;
  const AreaSplit wide_no_overlap = split_map_into_areas(map, options);
  EXPECT_GT(query_coverage(map, wide, 0.0).num_covered_best,
            query_coverage(map, wide_no_overlap, 0.0).num_covered_best);
  EXPECT_EQ(no_overlap.num_covered_any, eligible_query);
}

TEST(AreaSplit, TruncatesWhereLandmarksCannotBeSplit) {
  LandmarkMap map = test::corridor_map();
  // Landmarks 200..259 all at one place: no split separates them.
  for (landmark_t l = 200; l < 260; ++l) map.landmarks[l].position = Eigen::Vector3d(20.0, 0.0, 1.0);
  AreaSplitOptions options;
  options.max_classes = 40;
  options.overlap = 0.3;
  const AreaSplit split = split_map_into_areas(map, options);
  int64_t truncated = 0;
  for (const Area& a : split.areas) {
    EXPECT_LE(a.landmarks.size(), 40u);
    truncated += a.num_truncated;
  }
  EXPECT_GT(truncated, 0);
  // The 60 co-located landmarks cannot all fit: those left out are reported, nothing else is.
  const std::vector<landmark_t> uncovered = uncovered_landmarks(map, split);
  EXPECT_EQ(uncovered.size(), 20u);
  for (landmark_t l : uncovered) {
    EXPECT_GE(l, 200);
    EXPECT_LT(l, 260);
  }
}

TEST(AreaSplit, RejectsBadOptionsAndMaps) {
  const LandmarkMap map = test::corridor_map();
  AreaSplitOptions options;
  options.max_classes = 0;
  EXPECT_THROW(split_map_into_areas(map, options), Error);
  options = AreaSplitOptions();
  options.overlap = -1.0;
  EXPECT_THROW(split_map_into_areas(map, options), Error);
  options = AreaSplitOptions();
  options.min_observations = 1000;  // no landmark qualifies
  try {
    split_map_into_areas(map, options);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--min-observations"), std::string::npos) << e.what();
  }
  LandmarkMap bad = map;
  bad.keypoint_landmark[3] = 5000;
  EXPECT_THROW(split_map_into_areas(bad, AreaSplitOptions()), Error);
}

}  // namespace
}  // namespace lmb
