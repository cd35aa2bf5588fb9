#include "train/mapping/guided_matching.h"

#include <gtest/gtest.h>

#include "common/error.h"
#include "synthetic_scene.h"

namespace lmb {
namespace {

MatchingFrame frame_of(const test::SyntheticScene& s, int f) {
  return MatchingFrame(s.camera, s.frames[f].cam_from_world, s.frames[f].keypoints, s.frames[f].descriptors.data(), 64);
}

struct Quality {
  int correct = 0, wrong = 0, common = 0;
};

Quality judge(const test::SyntheticScene& s, int fa, int fb, const std::vector<Match>& matches) {
  Quality q;
  for (const Match& m : matches) {
    const int pa = s.keypoint_point[fa][m.a], pb = s.keypoint_point[fb][m.b];
    (pa >= 0 && pa == pb ? q.correct : q.wrong) += 1;
  }
  for (int pa : s.keypoint_point[fa]) {
    if (pa < 0) continue;
    for (int pb : s.keypoint_point[fb]) q.common += pa == pb ? 1 : 0;
  }
  return q;
}

TEST(GuidedMatching, FindsTrueMatchesDespiteAliasing) {
  test::SyntheticSceneOptions o;
  o.num_patterns = 150;  // ~17 points share each descriptor pattern
  o.unique_bits = 0;
  const test::SyntheticScene s = test::make_synthetic_scene(o);
  GuidedMatcher matcher{MatchingOptions{}};
  for (auto [fa, fb] : {std::pair{3, 5}, std::pair{10, 14}, std::pair{2, 31}}) {
    const MatchingFrame a = frame_of(s, fa), b = frame_of(s, fb);
    const auto matches = matcher.match(a, b);
    const Quality q = judge(s, fa, fb, matches);
    SCOPED_TRACE(testing::Message() << fa << "-" << fb << ": " << q.correct << " correct, " << q.wrong << " wrong, "
                                    << q.common << " common");
    EXPECT_GT(q.common, 50);
    EXPECT_LE(q.wrong, 0.02 * (q.correct + q.wrong));
    EXPECT_GE(q.correct, 0.6 * q.common);
    for (size_t i = 1; i < matches.size(); ++i) EXPECT_LT(matches[i - 1].a, matches[i].a);
  }
}

TEST(GuidedMatching, GridSearchEqualsExhaustiveSearch) {
  test::SyntheticSceneOptions o;
  o.num_patterns = 40;
  o.clutter_per_frame = 300;
  const test::SyntheticScene s = test::make_synthetic_scene(o);
  for (double max_scale_change : {0.0, 3.0}) {
    MatchingOptions grid;
    grid.ratio = 1.0;
    grid.max_scale_change = max_scale_change;
    grid.epipolar_threshold_px = 6.0;
    MatchingOptions exhaustive = grid;
    exhaustive.exhaustive_search = true;
    GuidedMatcher g(grid), e(exhaustive);
    for (auto [fa, fb] : {std::pair{0, 4}, std::pair{7, 33}, std::pair{20, 12}}) {
      const MatchingFrame a = frame_of(s, fa), b = frame_of(s, fb);
      std::vector<int> best_g, dist_g, best_e, dist_e;
      g.match_one_way(a, b, &best_g, &dist_g);
      e.match_one_way(a, b, &best_e, &dist_e);
      EXPECT_EQ(best_g, best_e);
      EXPECT_EQ(dist_g, dist_e);
      int found = 0;
      for (int x : best_g) found += x >= 0 ? 1 : 0;
      EXPECT_GT(found, 20);
    }
  }
}

TEST(GuidedMatching, EmptyFramesAndBadOptions) {
  test::SyntheticSceneOptions o;
  const test::SyntheticScene s = test::make_synthetic_scene(o);
  const std::vector<Keypoint> none;
  const MatchingFrame empty(s.camera, s.frames[0].cam_from_world, none, nullptr, 64);
  GuidedMatcher matcher{MatchingOptions{}};
  EXPECT_TRUE(matcher.match(empty, frame_of(s, 1)).empty());
  EXPECT_TRUE(matcher.match(frame_of(s, 1), empty).empty());
  MatchingOptions bad;
  bad.min_depth = 5;
  bad.max_depth = 1;
  EXPECT_THROW(GuidedMatcher{bad}, Error);
  bad = MatchingOptions{};
  bad.epipolar_threshold_px = 20;
  EXPECT_THROW(GuidedMatcher{bad}, Error);
}

}  // namespace
}  // namespace lmb
