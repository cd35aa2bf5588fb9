// Descriptor-distance fusion fitting: deterministic, its exemplars are every non-query observation
// of each class, its table is non-increasing, and its held-out precision@1 for every candidate
// weight equals a brute-force reference (dense stump sums of every class + the table at the
// nearest other exemplar, ranked with the classifier's tie rule).
#include "train/export/descriptor_fusion.h"
#include "infer/detail/scoring_index.h"

#include <algorithm>
#include <limits>
#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/hamming.h"
#include "common/random.h"
#include "infer/classifier.h"
#include "test/support/synthetic_map.h"
#include "train/boost/stump_learner.h"
#include "train/export/model_export.h"
#include "train/features/build_features.h"

namespace lmb {
namespace {

constexpr int kBytes = 16;

// 12 frames x 120 keypoints, 36 landmarks with a base descriptor each (a few bits flipped per
// observation), observed in most frames; landmarks 0..5 share two base descriptors (twins, which
// only the stumps can tell apart); the rest background. Frame 11 is a query frame.
LandmarkMap synthetic_map(uint64_t seed) {
  test::SyntheticMapSpec spec;
  spec.descriptor_bytes = kBytes;
  spec.num_landmarks = 36;
  spec.num_frames = 12;
  spec.keypoints_per_frame = 120;
  spec.track_probability = 0.8;
  spec.bit_flips = 10;
  spec.twins = 6;
  spec.random_roll = false;
  return test::synthetic_map(seed, spec);
}

struct Fixture {
  LandmarkMap map;
  Vocabulary vocabulary;
  ContextRegions regions;
  TrainingSet set;
  std::shared_ptr<const Model> model;  // without fusion
};

Fixture make_fixture(uint64_t seed, int rounds) {
  Fixture t;
  t.map = synthetic_map(seed);
  VocabularyTrainOptions vo;
  vo.num_words = 8;
  t.vocabulary = train_vocabulary(t.map.descriptors.data(), static_cast<int64_t>(t.map.keypoints.size()), kBytes, vo);
  ContextRegionOptions ro;
  ro.num_regions = 40;
  ro.seed = seed;
  t.regions = ContextRegions(ro);
  const std::vector<uint8_t> words = keypoint_words(t.map, t.vocabulary);
  TrainingSetOptions so;
  so.top_k_landmarks = 30;
  so.validation_fraction = 0.25;
  so.background_cap = 400;
  t.set = build_training_set(t.map, std::vector<int32_t>(words.begin(), words.end()), so);
  const FeatureMatrix features = build_training_features(t.map, t.regions, t.vocabulary, t.set.sample_keypoint, {});
  BoostOptions bo;
  bo.num_rounds = rounds;
  bo.dims_per_round = 100;
  bo.validation.interval = 0;
  SerialStumpLearner learner(features, t.set, bo);
  learner.train();
  t.model = std::make_shared<const Model>(export_model_data(learner.model(), t.map, t.vocabulary, t.regions));
  return t;
}

// Greedy k-centre written out plainly: the medoid (smallest distance sum, first on ties), then the
// farthest from the chosen (first on ties), returned ascending.
std::vector<int64_t> reference_k_centre(const LandmarkMap& map, const std::vector<int64_t>& keys, int32_t cap) {
  if (cap == 0 || static_cast<int64_t>(keys.size()) <= cap) return keys;
  const int bytes = map.descriptor_bytes;
  auto dist = [&](size_t i, size_t j) {
    return hamming_distance(map.descriptor(keys[i]), map.descriptor(keys[j]), bytes);
  };
  size_t medoid = 0;
  long best = -1;
  for (size_t i = 0; i < keys.size(); ++i) {
    long sum = 0;
    for (size_t j = 0; j < keys.size(); ++j) sum += dist(i, j);
    if (best < 0 || sum < best) {
      best = sum;
      medoid = i;
    }
  }
  std::vector<size_t> chosen = {medoid};
  while (chosen.size() < static_cast<size_t>(cap)) {
    size_t far = keys.size();
    int far_d = -1;
    for (size_t j = 0; j < keys.size(); ++j) {
      if (std::find(chosen.begin(), chosen.end(), j) != chosen.end()) continue;
      int nearest = 8 * bytes + 1;
      for (size_t i : chosen) nearest = std::min(nearest, dist(i, j));
      if (nearest > far_d) {
        far_d = nearest;
        far = j;
      }
    }
    chosen.push_back(far);
  }
  std::vector<int64_t> out;
  for (size_t i : chosen) out.push_back(keys[i]);
  std::sort(out.begin(), out.end());
  return out;
}

TEST(DescriptorFusion, KCentreExemplarsKnownAnswerAndBruteForce) {
  const Fixture t = make_fixture(5, 1);
  // Known answer: descriptors 0...0, 0...01 and 1...1: the medoid is the one-bit descriptor (sum
  // 1 + 127 against 1 + 128 and 128 + 127), the farthest from it all ones.
  LandmarkMap m = t.map;
  const std::vector<int64_t> three = {3, 7, 11};
  std::fill_n(m.descriptors.begin() + 3 * kBytes, kBytes, 0x00);
  std::fill_n(m.descriptors.begin() + 7 * kBytes, kBytes, 0x00);
  m.descriptors[7 * kBytes] = 0x01;
  std::fill_n(m.descriptors.begin() + 11 * kBytes, kBytes, 0xff);
  EXPECT_EQ(k_centre_exemplars(m, three, 1), std::vector<int64_t>({7}));
  EXPECT_EQ(k_centre_exemplars(m, three, 2), std::vector<int64_t>({7, 11}));
  EXPECT_EQ(k_centre_exemplars(m, three, 3), three);
  EXPECT_EQ(k_centre_exemplars(m, three, 0), three);
  EXPECT_THROW(k_centre_exemplars(m, three, -1), Error);
  // Every class's observations of the synthetic map, every cap: the plain reference.
  std::vector<landmark_t> classes(t.set.class_landmark.begin(), t.set.class_landmark.end());
  const std::vector<std::vector<int64_t>> of = exemplar_keypoints(t.map, classes);
  int64_t capped = 0;
  for (const std::vector<int64_t>& keys : of) {
    for (int32_t cap : {1, 2, 3, 5}) {
      const std::vector<int64_t> got = k_centre_exemplars(t.map, keys, cap);
      EXPECT_EQ(got, reference_k_centre(t.map, keys, cap)) << "cap " << cap;
      EXPECT_EQ(static_cast<int64_t>(got.size()), std::min<int64_t>(cap, static_cast<int64_t>(keys.size())));
      capped += static_cast<int64_t>(keys.size()) > cap;
    }
  }
  EXPECT_GT(capped, 50);
}

// The fit of `cap` exemplars a class (0: every observation) against the brute force.
void check_fit_against_brute_force(const Fixture& t, int32_t cap) {
  DescriptorFusionOptions o;
  o.max_exemplars = cap;
  DescriptorFusionStats stats, again_stats;
  const DescriptorFusion fusion = fit_descriptor_fusion(*t.model, t.map, t.set, o, &stats);
  const DescriptorFusion again = fit_descriptor_fusion(*t.model, t.map, t.set, o, &again_stats);
  EXPECT_EQ(fusion.exemplar_begin, again.exemplar_begin);
  EXPECT_EQ(fusion.exemplars, again.exemplars);
  EXPECT_EQ(fusion.distance_score, again.distance_score);
  EXPECT_EQ(stats.weight_p1, again_stats.weight_p1);

  // Exemplars: every non-query observation of each class, by ascending keypoint; with a cap, the
  // k-centre choice among those not held out.
  const int32_t C = t.model->num_classes();
  ASSERT_EQ(fusion.exemplar_begin.size(), static_cast<size_t>(C) + 1);
  std::vector<std::vector<int64_t>> obs(static_cast<size_t>(C));
  std::vector<int32_t> class_of(t.map.landmarks.size(), -1);
  for (int32_t c = 0; c < C; ++c) class_of[t.model->class_landmark(c)] = c;
  std::vector<int64_t> held_out;
  for (int64_t s = 0; s < t.set.num_samples(); ++s) {
    if (t.set.sample_is_validation[s] && t.set.sample_class[s] < C) held_out.push_back(t.set.sample_keypoint[s]);
  }
  for (const MapFrame& f : t.map.frames) {
    if (f.is_query) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      const landmark_t l = t.map.keypoint_landmark[k];
      const bool held = std::find(held_out.begin(), held_out.end(), k) != held_out.end();
      if (l != kInvalidLandmarkId && class_of[l] >= 0 && (cap == 0 || !held)) obs[class_of[l]].push_back(k);
    }
  }
  for (std::vector<int64_t>& keys : obs) keys = reference_k_centre(t.map, keys, cap);
  EXPECT_EQ(stats.exemplars, fusion.exemplar_begin.back());
  for (int32_t c = 0; c < C; ++c) {
    ASSERT_EQ(fusion.exemplar_begin[c + 1] - fusion.exemplar_begin[c], static_cast<int64_t>(obs[c].size()));
    for (size_t i = 0; i < obs[c].size(); ++i) {
      EXPECT_TRUE(std::equal(t.map.descriptor(obs[c][i]), t.map.descriptor(obs[c][i]) + kBytes,
                             fusion.exemplars.data() + (fusion.exemplar_begin[c] + static_cast<int64_t>(i)) * kBytes));
    }
  }
  // The table: weight x a non-increasing ratio; small distances favour the class.
  ASSERT_EQ(fusion.distance_score.size(), static_cast<size_t>(8 * kBytes + 1));
  for (size_t d = 1; d < fusion.distance_score.size(); ++d) {
    EXPECT_LE(fusion.distance_score[d], fusion.distance_score[d - 1]);
  }
  EXPECT_GT(stats.weight, 0.0);
  EXPECT_GT(fusion.distance_score.front(), 0.0);
  EXPECT_LT(fusion.distance_score.back(), 0.0);

  // Brute force: every held-out observation, dense scores of every class, the smallest distance
  // to the class's other observations; P@1 for each candidate weight.
  Classifier classifier(t.model);
  const std::vector<uint8_t> words = keypoint_words(t.map, t.model->vocabulary());
  const std::vector<frame_t> frame_of = keypoint_frames(t.map);
  std::vector<uint8_t> values(t.model->scoring().used_dims().size());
  std::vector<double> scores(static_cast<size_t>(C) + 1);
  std::vector<std::vector<double>> h;
  std::vector<std::vector<int>> dist;
  std::vector<int32_t> truth;
  for (int64_t s = 0; s < t.set.num_samples(); ++s) {
    if (!t.set.sample_is_validation[s] || t.set.sample_class[s] >= C) continue;
    const int64_t k = t.set.sample_keypoint[s];
    const frame_t f = frame_of[k];
    classifier.index_frame(map_frame_keypoints(t.map, f, words));
    classifier.compute_used_values(static_cast<int32_t>(k - t.map.frames[f].first_keypoint), t.map.descriptor(k),
                                   values.data());
    classifier.dense_scores(values.data(), scores.data());
    h.emplace_back(scores.begin(), scores.begin() + C);
    std::vector<int> d(static_cast<size_t>(C), 8 * kBytes);
    for (int32_t c = 0; c < C; ++c) {
      for (int64_t o2 : obs[c]) {
        if (o2 != k) d[c] = std::min(d[c], hamming_distance(t.map.descriptor(k), t.map.descriptor(o2), kBytes));
      }
    }
    dist.push_back(d);
    truth.push_back(t.set.sample_class[s]);
  }
  ASSERT_GT(truth.size(), 20u);
  EXPECT_EQ(stats.fit_samples, static_cast<int64_t>(truth.size()));
  ASSERT_EQ(stats.weight_p1.size(), o.weights.size());
  ASSERT_EQ(stats.distance_ratio.size(), fusion.distance_score.size());
  for (size_t d = 0; d < fusion.distance_score.size(); ++d) {
    EXPECT_EQ(fusion.distance_score[d], stats.weight * stats.distance_ratio[d]);
  }
  for (size_t i = 0; i < o.weights.size(); ++i) {
    int hits = 0;
    for (size_t j = 0; j < truth.size(); ++j) {
      double best = -std::numeric_limits<double>::infinity();
      int32_t best_c = -1;
      for (int32_t c = 0; c < C; ++c) {
        const double f = h[j][c] + o.weights[i] * stats.distance_ratio[dist[j][c]];
        if (f > best) {
          best = f;
          best_c = c;
        }
      }
      hits += best_c == truth[j];
    }
    EXPECT_EQ(stats.weight_p1[i], static_cast<double>(hits) / static_cast<double>(truth.size()))
        << "weight " << o.weights[i];
  }
  // The descriptors separate all but the twins: the fused ranking beats the stump sums alone.
  EXPECT_GT(stats.fit_p1_with, stats.fit_p1_without);
}

TEST(DescriptorFusion, FitIsDeterministicAndEqualsTheBruteForceReference) {
  check_fit_against_brute_force(make_fixture(5, 12), 0);
}

// Two exemplars a class (most classes have more than 2 observations outside the held-out ones):
// the stored rows are the k-centre choice, and the shape and weight are fitted with them.
TEST(DescriptorFusion, CappedExemplarsFitEqualsTheBruteForceReference) {
  const Fixture t = make_fixture(5, 12);
  check_fit_against_brute_force(t, 2);
  DescriptorFusionOptions o;
  o.max_exemplars = 2;
  const DescriptorFusion capped = fit_descriptor_fusion(*t.model, t.map, t.set, o);
  const DescriptorFusion all = fit_descriptor_fusion(*t.model, t.map, t.set, {});
  EXPECT_LT(capped.exemplars.size(), all.exemplars.size() / 2);
  // A cap no class reaches keeps every observation but the held-out ones.
  o.max_exemplars = 1000;
  const DescriptorFusion loose = fit_descriptor_fusion(*t.model, t.map, t.set, o);
  EXPECT_LT(loose.exemplars.size(), all.exemplars.size());
  EXPECT_GT(loose.exemplars.size(), capped.exemplars.size());
  o.max_exemplars = -1;
  EXPECT_THROW(fit_descriptor_fusion(*t.model, t.map, t.set, o), Error);
}

TEST(DescriptorFusion, RejectsAnotherRunsModelAndBadOptions) {
  const Fixture t = make_fixture(6, 4);
  TrainingSet other = t.set;
  std::swap(other.class_landmark[0], other.class_landmark[1]);
  EXPECT_THROW(fit_descriptor_fusion(*t.model, t.map, other, {}), Error);
  DescriptorFusionOptions o;
  o.weights = {0.5, 0.25};
  EXPECT_THROW(fit_descriptor_fusion(*t.model, t.map, t.set, o), Error);
  o = {};
  o.bin_width = 0;
  EXPECT_THROW(fit_descriptor_fusion(*t.model, t.map, t.set, o), Error);
}

}  // namespace
}  // namespace lmb
