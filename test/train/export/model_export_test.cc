// Export: the inference model scores exactly like the trainer's BoostModel, its inverted file
// lists the classes of each word, and (with the tiny world) a query frame is localized within
// 5 cm / 1 deg.
#include "train/export/model_export.h"
#include "infer/detail/scoring_index.h"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/io/map_h5.h"
#include "common/random.h"
#include "infer/classifier.h"
#include "infer/localizer.h"
#include "test/support/synthetic_map.h"
#include "train/boost/stump_learner.h"
#include "train/boost/training_set.h"
#include "train/features/build_features.h"

namespace lmb {
namespace {

constexpr int kBytes = 16;

// A map of 8 frames x 150 keypoints; 40 landmarks, each observed in 4..7 frames with its own base
// descriptor (a few bits flipped per observation); the rest background. Frame 7 is a query frame.
LandmarkMap synthetic_map(uint64_t seed) {
  test::SyntheticMapSpec spec;
  spec.descriptor_bytes = kBytes;
  return test::synthetic_map(seed, spec);
}

struct Trained {
  LandmarkMap map;
  Vocabulary vocabulary;
  ContextRegions regions;
  TrainingSet set;
  FeatureMatrix features;
  BoostModel boost;
};

Trained train_small(uint64_t seed, int rounds) {
  Trained t;
  t.map = synthetic_map(seed);
  VocabularyTrainOptions vo;
  vo.num_words = 8;
  t.vocabulary = train_vocabulary(t.map.descriptors.data(), static_cast<int64_t>(t.map.keypoints.size()), kBytes, vo);
  ContextRegionOptions ro;
  ro.num_regions = 40;
  ro.seed = seed;
  t.regions = ContextRegions(ro);
  const std::vector<uint8_t> words = keypoint_words(t.map, t.vocabulary);
  const std::vector<int32_t> words32(words.begin(), words.end());
  TrainingSetOptions so;
  so.top_k_landmarks = 30;
  so.validation_fraction = 0.0;
  so.background_cap = 400;
  t.set = build_training_set(t.map, words32, so);
  t.features = build_training_features(t.map, t.regions, t.vocabulary, t.set.sample_keypoint, {});
  BoostOptions bo;
  bo.num_rounds = rounds;
  bo.dims_per_round = 100;
  bo.validation.interval = 0;
  SerialStumpLearner learner(t.features, t.set, bo);
  learner.train();
  t.boost = learner.model();
  return t;
}

TEST(ModelExportTest, ExportedScoresEqualTheTrainersScores) {
  const Trained t = train_small(3, 60);
  ExportStats stats;
  const auto model =
      std::make_shared<const Model>(export_model_data(t.boost, t.map, t.vocabulary, t.regions, {}, &stats));
  EXPECT_EQ(stats.num_classes, t.boost.num_classes);
  EXPECT_GT(stats.num_stumps, 0);
  // Through the file, as an app gets it.
  const std::vector<uint8_t> bytes = model->to_bytes();
  const auto loaded = Model::from_bytes(bytes.data(), bytes.size());

  const int32_t C = t.boost.num_classes;
  const int64_t n = t.set.num_samples();
  const int32_t D = t.features.num_dims;
  ClassifierOptions dense_options;
  ClassifierOptions inverted_options;
  inverted_options.use_inverted_file = true;
  Classifier dense(loaded, dense_options), inverted(loaded, inverted_options);
  std::vector<uint8_t> row(static_cast<size_t>(D)), values(loaded->scoring().used_dims().size());
  std::vector<double> trainer(static_cast<size_t>(C) + 1), ours(static_cast<size_t>(C) + 1);
  const std::vector<uint8_t> words = keypoint_words(t.map, t.vocabulary);
  int64_t compared = 0;
  for (frame_t f = 0; f < t.map.num_frames(); ++f) {
    const FrameKeypoints frame = map_frame_keypoints(t.map, f, words);
    dense.index_frame(frame);
    for (int64_t i = 0; i < n; ++i) {
      if (t.set.sample_frame[i] != f) continue;
      const int64_t kp = t.set.sample_keypoint[i];
      const int32_t k = static_cast<int32_t>(kp - t.map.frames[f].first_keypoint);
      for (int32_t d = 0; d < D; ++d) row[d] = t.features.column(d)[i];
      t.boost.scores(row.data(), trainer.data());
      dense.compute_used_values(k, t.map.descriptor(kp), values.data());
      dense.dense_scores(values.data(), ours.data());
      for (int32_t c = 0; c <= C; ++c) {
        ASSERT_EQ(ours[c], trainer[c]) << "sample " << i << " class " << c;  // bit-identical
        ASSERT_EQ(dense.class_score(values.data(), c), trainer[c]);
      }
      ++compared;
    }
  }
  EXPECT_EQ(compared, n);

  // Whole-frame classification: the top-1 of every keypoint is the trainer's classify(), and the
  // inverted file gives the same top-1 whenever the true class is among the word's candidates.
  for (frame_t f = 0; f < t.map.num_frames(); ++f) {
    const MapFrame& mf = t.map.frames[f];
    const FrameKeypoints frame = map_frame_keypoints(t.map, f, words);
    const KeypointMatches a = dense.classify(frame, t.map.descriptor(mf.first_keypoint));
    const KeypointMatches b = inverted.classify(frame, t.map.descriptor(mf.first_keypoint));
    for (int32_t k = 0; k < mf.num_keypoints; ++k) {
      if (b.count(k) > 0) {
        ASSERT_GT(a.count(k), 0);
        // A candidate that beats the background in the inverted file beats it densely too.
        EXPECT_GE(a.of(k)[0].score, b.of(k)[0].score);
      }
      if (a.count(k) > 0) {
        const auto& list = loaded->data().inverted_file[frame.word[k]];
        if (std::binary_search(list.begin(), list.end(), a.of(k)[0].cls)) {
          ASSERT_GT(b.count(k), 0);
          EXPECT_EQ(b.of(k)[0].cls, a.of(k)[0].cls);
          EXPECT_EQ(b.of(k)[0].score, a.of(k)[0].score);
        }
      }
    }
  }
}

TEST(ModelExportTest, InvertedFileListsTheClassesOfEachWord) {
  const Trained t = train_small(4, 10);
  const std::vector<uint8_t> words = keypoint_words(t.map, t.vocabulary);
  for (int32_t min_obs : {1, 2}) {
    ExportOptions o;
    o.min_word_observations = min_obs;
    const ModelData d = export_model_data(t.boost, t.map, t.vocabulary, t.regions, o);
    for (int32_t c = 0; c < d.num_classes; ++c) {
      EXPECT_EQ(d.class_position[c], t.map.landmarks[d.class_landmark[c]].position);
      std::vector<int> count(static_cast<size_t>(t.vocabulary.num_words()), 0);
      for (const MapFrame& f : t.map.frames) {
        if (f.is_query) continue;
        for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
          if (t.map.keypoint_landmark[k] == d.class_landmark[c]) ++count[words[k]];
        }
      }
      for (int32_t w = 0; w < t.vocabulary.num_words(); ++w) {
        const auto& list = d.inverted_file[w];
        EXPECT_EQ(std::binary_search(list.begin(), list.end(), c), count[w] >= min_obs)
            << "class " << c << " word " << w;
      }
    }
  }
}

TEST(ModelExportTest, RejectsMismatchedPieces) {
  const Trained t = train_small(5, 5);
  ContextRegionOptions ro;
  ro.num_regions = 41;  // not the training regions
  EXPECT_THROW(export_model_data(t.boost, t.map, t.vocabulary, ContextRegions(ro)), Error);
  BoostModel b = t.boost;
  b.class_landmark[0] = 1000;  // not in the map
  EXPECT_THROW(export_model_data(b, t.map, t.vocabulary, t.regions), Error);
  ExportOptions o;
  o.min_word_observations = 0;
  EXPECT_THROW(export_model_data(t.boost, t.map, t.vocabulary, t.regions, o), Error);
}

// The tiny rendered world, mapped by the fixture (test/train/export/CMakeLists.txt): train a
// model on its map frames with the learner's API, export it, localize its query frames.
TEST(ModelExportTest, TinyWorldQueryFrameWithin5cm1deg) {
  const char* map_path = std::getenv("LMB_TINY_MAP");
  if (map_path == nullptr || !std::filesystem::exists(map_path)) {
    GTEST_SKIP() << "LMB_TINY_MAP (a map.h5 of `lboost world --preset tiny`) is not available";
  }
  const LandmarkMap map = read_map_h5(map_path);
  // The vocabulary from the map frames' own descriptors (the tests have no unrelated images).
  std::vector<uint8_t> train_desc;
  for (const MapFrame& f : map.frames) {
    if (f.is_query) continue;
    train_desc.insert(train_desc.end(), map.descriptor(f.first_keypoint),
                      map.descriptor(f.first_keypoint + f.num_keypoints));
  }
  VocabularyTrainOptions vo;
  vo.num_words = 16;
  const Vocabulary vocabulary = train_vocabulary(
      train_desc.data(), static_cast<int64_t>(train_desc.size()) / map.descriptor_bytes, map.descriptor_bytes, vo);
  ContextRegionOptions ro;
  ro.num_regions = 200;
  const ContextRegions regions(ro);
  const std::vector<uint8_t> words = keypoint_words(map, vocabulary);
  const std::vector<int32_t> words32(words.begin(), words.end());
  TrainingSetOptions so;
  so.validation_fraction = 0.0;
  so.background_cap = 6000;
  const TrainingSet set = build_training_set(map, words32, so);
  FeatureBuildOptions fo;
  fo.num_threads = 2;
  const FeatureMatrix features = build_training_features(map, regions, vocabulary, set.sample_keypoint, fo);
  BoostOptions bo;
  bo.num_rounds = std::getenv("LMB_TINY_ROUNDS") ? std::atoi(std::getenv("LMB_TINY_ROUNDS")) : 120;
  bo.dims_per_round = 300;
  bo.validation.interval = 0;
  SerialStumpLearner learner(features, set, bo);
  learner.train();
  const auto model = std::make_shared<const Model>(export_model_data(learner.model(), map, vocabulary, regions));

  // The tiny model is trained briefly: few keypoints beat the background, so every keypoint's
  // best class is kept and RANSAC gets the max_correspondences with the largest margins.
  const char* settings[] = {"margin 0", "no rejection, best 100 margins"};
  int best_good = 0, queries = 0;
  for (int setting = 0; setting < 2; ++setting) {
    LocalizerOptions lo;
    lo.pose.seed = 1;
    if (setting == 1) {
      lo.classifier.min_margin = -std::numeric_limits<double>::infinity();
      lo.max_correspondences = 100;
      lo.pose.max_iterations = 2000;
    }
    const Localizer localizer(model, lo);
    int good = 0;
    queries = 0;
    for (const MapFrame& f : map.frames) {
      if (!f.is_query) continue;
      ++queries;
      const std::vector<Keypoint> kps(map.keypoints.begin() + f.first_keypoint,
                                      map.keypoints.begin() + f.first_keypoint + f.num_keypoints);
      const LocalizeResult r =
          localizer.localize(map.cameras[f.camera], kps, map.descriptor(f.first_keypoint), f.gravity_in_cam);
      const double pe = position_error(r.pose.cam_from_world, f.cam_from_world);
      const double re = rotation_error_deg(r.pose.cam_from_world, f.cam_from_world);
      std::printf("%s, %s: success %d, %d/%zu inliers, %.3f m, %.2f deg\n", settings[setting], f.name.c_str(),
                  r.pose.success, r.pose.num_inliers, r.correspondence_keypoint.size(), pe, re);
      if (r.pose.success && pe <= 0.05 && re <= 1.0) ++good;
    }
    std::printf("%s: %d of %d query frames within 5 cm / 1 deg\n", settings[setting], good, queries);
    best_good = std::max(best_good, good);
  }
  EXPECT_GE(best_good, 1) << "no query frame within 5 cm / 1 deg";
  EXPECT_GE(best_good * 2, queries) << "fewer than half of the query frames within 5 cm / 1 deg";
}

}  // namespace
}  // namespace lmb
