// Localizer: the code model of test_models.h on a synthetic frame (known matches, known pose),
// determinism across threads, and the options.
#include "infer/localizer.h"

#include <memory>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/context_embedding.h"
#include "common/error.h"
#include "infer/classifier.h"
#include "test/infer/test_models.h"

namespace lmb {
namespace {

struct Fixture {
  test::TestWorld world = test::make_test_world(101, 60, 140, 21);
  std::shared_ptr<const Model> model = std::make_shared<const Model>(test::make_code_model_data(world.positions));
};

LocalizeResult run(const Localizer& localizer, const test::TestFrame& f) {
  return localizer.localize(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
}

void expect_same_matches(const KeypointMatches& a, const KeypointMatches& b) {
  EXPECT_EQ(a.begin, b.begin);
  ASSERT_EQ(a.matches.size(), b.matches.size());
  for (size_t m = 0; m < a.matches.size(); ++m) {
    EXPECT_EQ(a.matches[m].cls, b.matches[m].cls);
    EXPECT_EQ(a.matches[m].score, b.matches[m].score);
    EXPECT_EQ(a.matches[m].background_score, b.matches[m].background_score);
  }
}

void expect_same_localization(const LocalizeResult& a, const LocalizeResult& b) {
  expect_same_matches(a.matches, b.matches);
  EXPECT_EQ(a.correspondence_keypoint, b.correspondence_keypoint);
  EXPECT_EQ(a.pose.success, b.pose.success);
  EXPECT_EQ(a.pose.inlier_mask, b.pose.inlier_mask);
  EXPECT_EQ(a.pose.cam_from_world.rotation.coeffs(), b.pose.cam_from_world.rotation.coeffs());
  EXPECT_EQ(a.pose.cam_from_world.translation, b.pose.cam_from_world.translation);
}

TEST(LocalizerTest, FindsTheMatchesAndThePose) {
  const Fixture fx;
  const test::TestFrame& f = fx.world.frame;
  for (bool inverted : {false, true}) {
    LocalizerOptions o;
    o.classifier.use_inverted_file = inverted;
    const Localizer localizer(fx.model, o);
    const LocalizeResult r = run(localizer, f);
    ASSERT_EQ(r.matches.num_keypoints(), static_cast<int32_t>(f.keypoints.size()));
    int correct = 0, wrong = 0;
    for (int32_t k = 0; k < r.matches.num_keypoints(); ++k) {
      if (f.keypoint_class[k] >= 0) {
        ASSERT_EQ(r.matches.count(k), 1) << "keypoint " << k;
        EXPECT_EQ(r.matches.of(k)[0].cls, f.keypoint_class[k]);
        EXPECT_EQ(r.matches.of(k)[0].landmark, fx.model->class_landmark(f.keypoint_class[k]));
        ++correct;
      } else {
        wrong += r.matches.count(k);  // a random descriptor matching a code by chance
      }
    }
    EXPECT_EQ(correct, 60);
    EXPECT_LE(wrong, 2);
    ASSERT_TRUE(r.pose.success);
    EXPECT_GE(r.pose.num_inliers, 60);
    EXPECT_LT(position_error(r.pose.cam_from_world, f.cam_from_world), 1e-3);
    EXPECT_LT(rotation_error_deg(r.pose.cam_from_world, f.cam_from_world), 0.01);
    EXPECT_EQ(r.correspondence_keypoint.size(), r.pose.inlier_mask.size());
    EXPECT_GT(r.timings.total_ms, 0.0);
  }
}

TEST(LocalizerTest, FourThreadsGiveTheSameResultsAsOne) {
  const Fixture fx;
  // Several frames: the same world seen with different outlier sets.
  std::vector<test::TestFrame> frames;
  for (uint64_t s = 0; s < 6; ++s) {
    test::TestWorld w = test::make_test_world(101, 30 + 5 * static_cast<int>(s), 150, 21);
    frames.push_back(w.frame);
  }
  LocalizerOptions o;
  o.classifier.top_k = 2;
  o.pose_top_k = 2;
  const Localizer localizer(fx.model, o);
  std::vector<LocalizeResult> serial;
  for (const auto& f : frames) serial.push_back(run(localizer, f));
  std::vector<std::vector<LocalizeResult>> parallel(4);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      for (int rep = 0; rep < 3; ++rep) {
        for (size_t i = 0; i < frames.size(); ++i) {
          const size_t j = (i + static_cast<size_t>(t)) % frames.size();  // different orders
          LocalizeResult r = run(localizer, frames[j]);
          if (rep == 2) {
            if (parallel[t].empty()) parallel[t].resize(frames.size());
            parallel[t][j] = std::move(r);
          }
        }
      }
    });
  }
  for (auto& th : threads) th.join();
  for (int t = 0; t < 4; ++t) {
    for (size_t i = 0; i < frames.size(); ++i) {
      expect_same_localization(serial[i], parallel[t][i]);
      EXPECT_TRUE(serial[i].pose.success);
    }
  }
}

TEST(LocalizerTest, APreparedFrameServesEveryModelOfItsVocabularyWithTheSameResult) {
  const Fixture fx;
  const test::TestFrame& f = fx.world.frame;
  // A second model of the same vocabulary and regions whose context stumps count (a != 0), so a
  // context index read wrongly would change its scores; the first model prepares the frame.
  ModelData other = test::make_code_model_data(fx.world.positions, 2);
  int context_stumps = 0;
  for (SharedStump& s : other.stumps) {
    if (s.dim < other.regions.size() * other.vocabulary.num_words()) {
      s.a = 0.5 + 0.125 * (context_stumps++ % 5);
      s.theta = static_cast<uint8_t>(s.theta % 3);
    }
  }
  ASSERT_GT(context_stumps, 0);
  const auto second = std::make_shared<const Model>(std::move(other));
  const PreparedFrame prepared(fx.model, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
  EXPECT_EQ(prepared.size(), static_cast<int32_t>(f.keypoints.size()));
  for (const auto& model : {fx.model, second}) {
    ASSERT_TRUE(prepared.serves(*model));
    for (bool inverted : {false, true}) {
      LocalizerOptions o;
      o.classifier.use_inverted_file = inverted;
      o.classifier.top_k = 3;
      o.pose_top_k = 2;
      const Localizer localizer(model, o);
      const LocalizeResult scratch = run(localizer, f);
      const LocalizeResult shared = localizer.localize(f.camera, f.keypoints, f.descriptors.data(), prepared, o);
      expect_same_localization(scratch, shared);
      // The reference: the classifier indexing the frame itself.
      const int32_t n = static_cast<int32_t>(f.keypoints.size());
      std::vector<uint8_t> words(static_cast<size_t>(n));
      model->vocabulary().quantize(f.descriptors.data(), n, words.data());
      const FrameKeypoints frame =
          frame_keypoints_from_detections(f.camera, f.keypoints.data(), words.data(), n, f.gravity_in_cam, "test");
      Classifier classifier(model, o.classifier);
      expect_same_matches(classifier.classify(frame, f.descriptors.data()), shared.matches);
      EXPECT_EQ(shared.timings.words_ms, 0.0);  // the prepared frame's work is not this call's
      EXPECT_TRUE(shared.pose.success);
    }
  }
  // The context stumps of the second model changed its scores: the test can tell a wrong index.
  const LocalizeResult a = run(Localizer(fx.model), f), b = run(Localizer(second), f);
  ASSERT_EQ(a.matches.begin, b.matches.begin);
  int differ = 0;
  for (size_t m = 0; m < a.matches.matches.size(); ++m)
    differ += a.matches.matches[m].score != b.matches.matches[m].score;
  EXPECT_GT(differ, 10);

  // Another vocabulary or region count: not served, and refused rather than read wrongly.
  ModelData words = test::make_code_model_data(fx.world.positions);
  words.vocabulary = test::test_vocabulary(6);
  ModelData regions = test::make_code_model_data(fx.world.positions);
  regions.regions = ContextRegions({{-4.f, -4.f, 4.f, 4.f}, {-1.f, 0.f, 3.f, 8.f}});
  for (ModelData* d : {&words, &regions}) {
    const int32_t dims = d->regions.size() * d->vocabulary.num_words();
    for (SharedStump& s : d->stumps) {
      if (s.dim >= 3 * 4)
        s.dim = s.dim - 3 * 4 + dims;  // the descriptor bits after the context
      else
        s.dim %= dims;
    }
    const auto model = std::make_shared<const Model>(std::move(*d));
    EXPECT_FALSE(prepared.serves(*model));
    EXPECT_THROW(Localizer(model).localize(f.camera, f.keypoints, f.descriptors.data(), prepared, LocalizerOptions{}),
                 Error);
  }
  // A prepared frame of other keypoints is refused.
  std::vector<Keypoint> fewer(f.keypoints.begin(), f.keypoints.end() - 1);
  EXPECT_THROW(Localizer(fx.model).localize(f.camera, fewer, f.descriptors.data(), prepared, LocalizerOptions{}),
               Error);
  EXPECT_THROW(PreparedFrame(nullptr, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam), Error);
  EXPECT_THROW(PreparedFrame(fx.model, f.camera, f.keypoints, nullptr, f.gravity_in_cam), Error);
}

TEST(LocalizerTest, TooFewMatchesIsNoPoseNotAnError) {
  const Fixture fx;
  test::TestWorld w = test::make_test_world(101, 5, 50, 21);
  const Localizer localizer(fx.model);
  const LocalizeResult r = run(localizer, w.frame);
  EXPECT_FALSE(r.pose.success);
  // An empty frame as well.
  const LocalizeResult e = localizer.localize(w.frame.camera, {}, nullptr, w.frame.gravity_in_cam);
  EXPECT_FALSE(e.pose.success);
  EXPECT_EQ(e.matches.num_keypoints(), 0);
}

TEST(LocalizerTest, RejectsInvalidInput) {
  const Fixture fx;
  const test::TestFrame& f = fx.world.frame;
  const Localizer localizer(fx.model);
  EXPECT_THROW(localizer.localize(f.camera, f.keypoints, nullptr, f.gravity_in_cam), Error);
  EXPECT_THROW(localizer.localize(f.camera, f.keypoints, f.descriptors.data(), Eigen::Vector3d::Zero()), Error);
  Camera bad = f.camera;
  bad.params = {500.0};
  EXPECT_THROW(localizer.localize(bad, f.keypoints, f.descriptors.data(), f.gravity_in_cam), Error);
  std::vector<Keypoint> kps = f.keypoints;
  kps[3].scale = 0.f;
  EXPECT_THROW(localizer.localize(f.camera, kps, f.descriptors.data(), f.gravity_in_cam), Error);
  LocalizerOptions o;
  o.pose_top_k = 2;  // > classifier.top_k
  EXPECT_THROW(Localizer(fx.model, o), Error);
  EXPECT_THROW(Localizer(nullptr), Error);
}

}  // namespace
}  // namespace lmb
