// The tracked rows on one process against a brute-force score table (the split over ranks is
// checked against this on real ranks by train/dist/feature_parallel_learner_test).
#include "train/boost/tracked_rows.h"

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/random.h"
#include "train/boost/synthetic_problem.h"

namespace lmb {
namespace {

TEST(TrackedRows, ScoresValidationAndPoolRowsLikeABruteForceTable) {
  SyntheticBoostOptions so;
  so.num_classes = 30;
  const SyntheticBoostProblem p = make_synthetic_boost_problem(so);
  const TrainingSet& set = p.set;
  const int32_t C1 = set.num_classes_with_background();
  BoostOptions o;
  o.validation.max_samples = 25;
  o.mining.pool_size = 40;
  TrackedRows rows(set, one_process());
  rows.select(o);
  ASSERT_EQ(rows.num_validation_rows(), 25);
  // Rows: validation samples of landmark classes, then training samples, each part ascending.
  std::vector<int64_t> samples;
  for (int64_t r = 0; r < 25; ++r) {
    samples.push_back(rows.sample(r));
    EXPECT_TRUE(set.sample_is_validation[rows.sample(r)]);
    EXPECT_LT(set.sample_class[rows.sample(r)], set.num_classes);
    if (r > 0) {
      EXPECT_LT(rows.sample(r - 1), rows.sample(r));
    }
  }
  int64_t pool = 0;
  rows.for_each_pool_row([&](int64_t r, int64_t s, const float*) {
    EXPECT_EQ(r, 25 + pool);
    EXPECT_FALSE(set.sample_is_validation[s]);
    samples.push_back(s);
    ++pool;
  });
  EXPECT_EQ(pool, 40);

  // Random stumps, some with large sharing sets (the dense update path).
  Rng rng(21);
  std::vector<std::vector<double>> table(samples.size(), std::vector<double>(static_cast<size_t>(C1), 0.0));
  std::vector<double> offset(static_cast<size_t>(C1), 0.0);
  for (int round = 0; round < 12; ++round) {
    std::vector<int32_t> classes;
    const double share = round % 3 == 0 ? 0.8 : 0.1;
    for (int32_t c = 0; c < C1; ++c) {
      if (rng.uniform() < share) classes.push_back(c);
    }
    std::vector<float> d_above, d_below;
    for (size_t j = 0; j < classes.size(); ++j) {
      d_above.push_back(static_cast<float>(rng.uniform(-1, 1)));
      d_below.push_back(static_cast<float>(rng.uniform(-1, 1)));
    }
    std::vector<uint8_t> above(static_cast<size_t>(set.num_samples()));
    for (auto& a : above) a = rng.uniform() < 0.5;
    std::vector<double> k(static_cast<size_t>(C1));
    for (double& x : k) x = rng.uniform(-0.2, 0.2);
    for (size_t i = 0; i < samples.size(); ++i) {
      for (size_t j = 0; j < classes.size(); ++j) {
        table[i][classes[j]] = static_cast<float>(table[i][classes[j]]) + (above[samples[i]] ? d_above[j] : d_below[j]);
      }
    }
    for (int32_t c = 0; c < C1; ++c) offset[c] += k[c];
    rows.add_stump(classes, d_above, d_below, above);
    rows.add_constants(k);
  }
  EXPECT_EQ(rows.class_offset(), offset);
  // Validation precision@1: the first best class over the landmarks, the background winning only
  // when strictly higher.
  int64_t all = 0, landmarks = 0;
  for (int64_t r = 0; r < 25; ++r) {
    int32_t best = 0;
    for (int32_t c = 1; c < C1 - 1; ++c) {
      if (offset[c] + table[r][c] > offset[best] + table[r][best]) best = c;
    }
    const bool hit = best == set.sample_class[samples[r]];
    landmarks += hit;
    all += hit && !(offset[C1 - 1] + table[r][C1 - 1] > offset[best] + table[r][best]);
  }
  double p_all = 0, p_landmarks = 0;
  rows.validation_precision(&p_all, &p_landmarks);
  EXPECT_EQ(p_all, static_cast<double>(all) / 25);
  EXPECT_EQ(p_landmarks, static_cast<double>(landmarks) / 25);
  // Pool rows: their pending stumps applied on reading, the same floats.
  rows.for_each_pool_row([&](int64_t r, int64_t, const float* scores) {
    for (int32_t c = 0; c < C1; ++c) EXPECT_EQ(scores[c], static_cast<float>(table[r][c])) << "row " << r;
  });
  // save / restore: the same table.
  LearnerState st;
  rows.save(&st);
  ASSERT_EQ(st.tracked_scores.size(), samples.size() * C1);
  for (size_t i = 0; i < samples.size(); ++i) {
    for (int32_t c = 0; c < C1; ++c) EXPECT_EQ(st.tracked_scores[i * C1 + c], static_cast<float>(table[i][c]));
  }
  TrackedRows restored(set, one_process());
  restored.check(st);
  restored.restore(st);
  double r_all = 0, r_landmarks = 0;
  restored.validation_precision(&r_all, &r_landmarks);
  EXPECT_EQ(r_all, p_all);
  st.tracked_samples[3] = set.num_samples();
  EXPECT_THROW(restored.check(st), Error);
}

}  // namespace
}  // namespace lmb
