// The negative sets as the learner bootstraps and mines them: through the visual words, class
// balanced, capped, never a duplicate, never a sample near the class's landmark.
#include "train/boost/negative_miner.h"

#include <map>
#include <set>

#include <gtest/gtest.h>

#include "train/boost/stump_learner.h"
#include "train/boost/synthetic_problem.h"

namespace lmb {
namespace {

TEST(NegativeMiner, BootstrapAndMiningRespectWordsAndExclusionRadius) {
  SyntheticBoostProblem p = make_synthetic_boost_problem(SyntheticBoostOptions());
  // Class 1 sits 1 cm from class 0: a likely SfM duplicate, never a negative of class 0.
  p.set.class_position[1] = p.set.class_position[0] + Eigen::Vector3d(0.01, 0, 0);
  for (int64_t s = 0; s < p.set.num_samples(); ++s) {
    if (p.set.sample_class[s] == 1) p.set.sample_position[s] = p.set.class_position[1].cast<float>();
  }
  BoostOptions o;
  o.num_rounds = 60;
  o.dims_per_round = 50;
  o.negatives.per_class = 10;
  o.mining.interval = 10;
  o.negatives.max_per_class = 30;
  SerialStumpLearner learner(p.features, p.set, o);
  learner.initialize();
  const int32_t C = p.set.num_classes;
  std::vector<std::set<int32_t>> words(static_cast<size_t>(C) + 1);
  for (int64_t s = 0; s < p.set.num_samples(); ++s) {
    if (!p.set.sample_is_validation[s]) words[p.set.sample_class[s]].insert(p.set.sample_word[s]);
  }
  std::vector<int> negatives(static_cast<size_t>(C) + 1, 0);
  std::vector<double> positive_weight(static_cast<size_t>(C) + 1, 0.0), negative_weight(positive_weight);
  int64_t landmark_train = 0;
  for (int64_t s = 0; s < p.set.num_samples(); ++s) {
    landmark_train += !p.set.sample_is_validation[s] && p.set.sample_class[s] < C;
  }
  for (const auto& e : learner.entries()) {
    EXPECT_FALSE(p.set.sample_is_validation[e.sample]);
    if (e.z > 0) {
      EXPECT_DOUBLE_EQ(e.weight, 1.0);
      EXPECT_EQ(p.set.sample_class[e.sample], e.cls);
      positive_weight[e.cls] += e.weight;
      continue;
    }
    ++negatives[e.cls];
    negative_weight[e.cls] += e.weight;
    EXPECT_NE(p.set.sample_class[e.sample], e.cls);
    if (e.cls < C) {
      EXPECT_TRUE(words[e.cls].count(p.set.sample_word[e.sample])) << "class " << e.cls;
    }
    if (e.cls == 0) {
      EXPECT_NE(p.set.sample_class[e.sample], 1);
    }
  }
  for (int32_t c = 0; c <= C; ++c) {
    EXPECT_GT(negatives[c], 0) << "class " << c;
    if (c < C) {
      EXPECT_LE(negatives[c], o.negatives.per_class);
    }
    // Class balance (negative_weight_ratio 1): a class's negatives weigh as much as its positives.
    EXPECT_NEAR(negative_weight[c], positive_weight[c], 1e-9 * positive_weight[c]) << "class " << c;
  }
  // The background class has every landmark training sample as a negative (background_negatives 0).
  EXPECT_EQ(negatives[C], landmark_train);
  learner.train();
  std::map<std::pair<int64_t, int32_t>, int> seen;
  std::vector<int> after(static_cast<size_t>(C) + 1, 0);
  for (const auto& e : learner.entries()) {
    EXPECT_EQ(++seen[std::make_pair(e.sample, e.cls)], 1) << "duplicate entry";
    if (e.z > 0) continue;
    ++after[e.cls];
    if (e.cls == 0) {
      EXPECT_NE(p.set.sample_class[e.sample], 1);
    }
  }
  int grown = 0;
  for (int32_t c = 0; c < C; ++c) {
    EXPECT_LE(after[c], o.negatives.max_per_class);
    grown += after[c] > negatives[c];
  }
  EXPECT_GT(grown, 0);
}

// The tracked scores the learner keeps incrementally (validation rows every round, mining-pool
// rows in batches between minings) equal the model's scores of those samples, after a mining step,
// between two and at the end; the validation P@1 equals a plain first-maximum count over them.

}  // namespace
}  // namespace lmb
