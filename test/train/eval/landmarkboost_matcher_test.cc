// LandmarkBoostMatcher + the pose stage against the inference library's Localizer on the code
// model of test/infer/test_models.h: the same correspondences and a bit-identical pose (dense and
// inverted file, with and without --max-correspondences and rejection), and a ranking that equals
// the Localizer's without rejection.
#include "train/eval/landmarkboost_matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <set>

#include <gtest/gtest.h>

#include "infer/localizer.h"
#include "test/infer/test_models.h"
#include "train/eval/pose_stage.h"

namespace lmb {
namespace {

struct Fixture {
  test::TestWorld world = test::make_test_world(101, 60, 140, 21);
  std::shared_ptr<const Model> model = std::make_shared<const Model>(test::make_code_model_data(world.positions));
  EvalQuery query() const {
    const test::TestFrame& f = world.frame;
    EvalQuery q;
    q.frame = 0;
    q.camera = &f.camera;
    q.keypoints = f.keypoints;
    q.descriptors = f.descriptors.data();
    q.gravity_in_cam = f.gravity_in_cam;
    q.true_cam_from_world = f.cam_from_world;
    return q;
  }
};

TEST(LandmarkBoostMatcherTest, PoseEqualsTheLocalizers) {
  const Fixture fx;
  const EvalQuery q = fx.query();
  for (bool inverted : {false, true}) {
    for (double margin : {0.0, -std::numeric_limits<double>::infinity()}) {
      for (int cap : {0, 25}) {
        SCOPED_TRACE(testing::Message() << "inverted " << inverted << " margin " << margin << " cap " << cap);
        LocalizerOptions o;
        o.classifier.top_k = 5;
        o.classifier.use_inverted_file = inverted;
        o.classifier.min_margin = margin;
        o.max_correspondences = cap;
        o.pose.seed = 3;
        const LocalizeResult expected =
            Localizer(fx.model, o).localize(*q.camera, q.keypoints, q.descriptors, q.gravity_in_cam);
        const LandmarkBoostMatcher matcher(fx.model, o.classifier);
        const FrameMatches m = matcher.match(q);
        const PoseInput input = select_correspondences(q, m.accepted, cap);
        ASSERT_EQ(input.pixels.size(), expected.correspondence_keypoint.size());
        for (size_t i = 0; i < input.pixels.size(); ++i) {
          const Keypoint& kp = q.keypoints[expected.correspondence_keypoint[i]];
          EXPECT_EQ(input.pixels[i], Eigen::Vector2d(kp.x, kp.y));
          EXPECT_EQ(input.points_world[i],
                    fx.model->class_position(expected.matches.matches[expected.correspondence_match[i]].cls));
        }
        const FrameOutcome outcome = estimate_frame_pose(q, input, o.pose);
        EXPECT_EQ(outcome.localized, expected.pose.success);
        EXPECT_EQ(outcome.num_inliers, expected.pose.num_inliers);
        EXPECT_EQ(outcome.cam_from_world.translation, expected.pose.cam_from_world.translation);
        EXPECT_EQ(outcome.cam_from_world.rotation.coeffs(), expected.pose.cam_from_world.rotation.coeffs());
        EXPECT_GE(m.match_ms, 0.0);
      }
    }
  }
}

TEST(LandmarkBoostMatcherTest, RankingIsTheLocalizersWithoutRejection) {
  const Fixture fx;
  const EvalQuery q = fx.query();
  LocalizerOptions o;
  o.classifier.top_k = 4;
  const FrameMatches m = LandmarkBoostMatcher(fx.model, o.classifier).match(q);
  o.classifier.min_margin = -std::numeric_limits<double>::infinity();
  const LocalizeResult all = Localizer(fx.model, o).localize(*q.camera, q.keypoints, q.descriptors, q.gravity_in_cam);
  ASSERT_EQ(m.ranking.size(), q.keypoints.size());
  int accepted = 0;
  for (int32_t k = 0; k < all.matches.num_keypoints(); ++k) {
    ASSERT_EQ(m.ranking[k].size(), static_cast<size_t>(all.matches.count(k)));
    ASSERT_EQ(m.ranking[k].size(), 4u);  // no rejection: every keypoint ranks top_k classes
    for (int32_t j = 0; j < all.matches.count(k); ++j) {
      const ClassMatch& c = all.matches.of(k)[j];
      EXPECT_EQ(m.ranking[k][j].landmark, c.landmark);
      EXPECT_EQ(m.ranking[k][j].score, c.score - c.background_score);
    }
    // Accepted (margin 0): exactly the keypoints whose best margin is positive.
    accepted += m.ranking[k][0].score > 0.0;
  }
  EXPECT_EQ(static_cast<int>(m.accepted.size()), accepted);
  EXPECT_GE(accepted, 60);
}

// accepted_without: per keypoint, the best class of the full ranking (every class, the same
// rejection) whose landmark is not excluded; nothing excluded = match()'s accepted matches.
TEST(LandmarkBoostMatcherTest, AcceptedWithoutIsTheBestRemainingClassOfTheFullRanking) {
  const Fixture fx;
  const EvalQuery q = fx.query();
  for (bool inverted : {false, true}) {
    for (double margin : {0.0, -std::numeric_limits<double>::infinity()}) {
      SCOPED_TRACE(testing::Message() << "inverted " << inverted << " margin " << margin);
      LocalizerOptions o;
      o.classifier.use_inverted_file = inverted;
      o.classifier.min_margin = margin;
      const LandmarkBoostMatcher matcher(fx.model, o.classifier);
      const FrameMatches m = matcher.match(q);
      const std::vector<Correspondence> same = matcher.accepted_without(q, [](landmark_t) { return false; });
      ASSERT_EQ(same.size(), m.accepted.size());
      for (size_t i = 0; i < same.size(); ++i) {
        EXPECT_EQ(same[i].keypoint, m.accepted[i].keypoint);
        EXPECT_EQ(same[i].landmark, m.accepted[i].landmark);
        EXPECT_EQ(same[i].point_world, m.accepted[i].point_world);
        EXPECT_EQ(same[i].confidence, m.accepted[i].confidence);
      }
      // Exclude every landmark some keypoint matched best: each keypoint falls back to its best
      // class outside that set, if one beats the background.
      std::set<landmark_t> best;
      for (const Correspondence& c : m.accepted) best.insert(c.landmark);
      const auto excluded = [&](landmark_t l) { return best.count(l) > 0; };
      o.classifier.top_k = fx.model->num_classes();
      const LocalizeResult full =
          Localizer(fx.model, o).localize(*q.camera, q.keypoints, q.descriptors, q.gravity_in_cam);
      std::vector<Correspondence> expected;
      for (int32_t k = 0; k < full.matches.num_keypoints(); ++k) {
        for (int32_t j = 0; j < full.matches.count(k); ++j) {
          const ClassMatch& c = full.matches.of(k)[j];
          if (excluded(c.landmark)) continue;
          expected.push_back(
              Correspondence{k, c.landmark, fx.model->class_position(c.cls), c.score - c.background_score});
          break;
        }
      }
      const std::vector<Correspondence> got = matcher.accepted_without(q, excluded);
      ASSERT_EQ(got.size(), expected.size());
      int moved = 0;
      for (size_t i = 0; i < got.size(); ++i) {
        EXPECT_EQ(got[i].keypoint, expected[i].keypoint);
        EXPECT_EQ(got[i].landmark, expected[i].landmark);
        EXPECT_EQ(got[i].point_world, expected[i].point_world);
        EXPECT_EQ(got[i].confidence, expected[i].confidence);
        EXPECT_FALSE(excluded(got[i].landmark));
        moved += std::any_of(m.accepted.begin(), m.accepted.end(),
                             [&](const Correspondence& c) { return c.keypoint == got[i].keypoint; });
      }
      // The case the pose calibration needs: keypoints matched before keep a (weaker) match;
      // without rejection every one (this code model's keypoints beat the background with one
      // class at most, so with margin 0 they lose theirs).
      if (std::isinf(margin)) {
        EXPECT_EQ(moved, static_cast<int>(m.accepted.size()));
      }
      EXPECT_TRUE(matcher.accepted_without(q, [](landmark_t) { return true; }).empty());
    }
  }
}

}  // namespace
}  // namespace lmb
