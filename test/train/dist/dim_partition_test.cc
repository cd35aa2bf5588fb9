// The feature-parallel learner's plans (pure functions, no MPI): every dim is screened and refined
// by exactly one rank, the blocked screening passes are balanced, and columns move only from a
// rank that has them.
#include "train/dist/dim_partition.h"

#include <algorithm>
#include <map>

#include <gtest/gtest.h>

#include "common/random.h"
#include "train/boost/column_screener.h"
#include "train/boost/feature_columns.h"

namespace lmb {
namespace {

TEST(DimPartition, RankDimsCoverEveryDimOnce) {
  for (int size : {1, 2, 3, 7}) {
    std::vector<int> owner(100, -1);
    for (int r = 0; r < size; ++r) {
      for (int32_t d : rank_dims(100, r, size)) {
        EXPECT_EQ(owner[d], -1);
        owner[d] = r;
        EXPECT_EQ(dim_owner(d, size), r);
      }
    }
    EXPECT_EQ(std::count(owner.begin(), owner.end(), -1), 0);
  }
}

TEST(DimPartition, ScreeningPlanBalancesTheBlockedPasses) {
  Rng rng(4);
  const int32_t num_dims = 2000;
  for (int trial = 0; trial < 40; ++trial) {
    const int size = 2 + static_cast<int>(rng.below(5));
    std::vector<uint8_t> kind(num_dims);
    for (auto& k : kind) k = static_cast<uint8_t>(rng.below(3));
    // A skewed draw: mostly dims of rank 0.
    std::vector<int32_t> round;
    for (int32_t d = 0; d < num_dims; ++d) {
      if (rng.uniform() < (dim_owner(d, size) == 0 ? 0.5 : 0.05)) round.push_back(d);
    }
    const ScreeningPlan plan = plan_screening(round, kind, size);
    ASSERT_EQ(plan.screener.size(), round.size());
    std::vector<int64_t> blocked(static_cast<size_t>(size), 0);
    int64_t total = 0;
    for (size_t i = 0; i < round.size(); ++i) {
      EXPECT_EQ(plan.screener[i].first, round[i]);
      const int r = plan.screener[i].second;
      if (kind[round[i]] != FeatureColumns::kBlocked) {
        EXPECT_EQ(r, dim_owner(round[i], size));
      }
      if (kind[round[i]] == FeatureColumns::kBlocked) ++blocked[r], ++total;
    }
    // No rank needs more blocked passes than the least possible maximum.
    const int64_t K = ColumnScreener::kBlockDims;
    const int64_t limit = K * (((total + K - 1) / K + size - 1) / size);
    for (int64_t n : blocked) EXPECT_LE(n, limit);
    // Moves: ascending dims, from the owner to the dim's screener.
    for (size_t i = 0; i < plan.moves.size(); ++i) {
      const ColumnMove& m = plan.moves[i];
      if (i > 0) {
        EXPECT_LT(plan.moves[i - 1].dim, m.dim);
      }
      EXPECT_EQ(m.from, dim_owner(m.dim, size));
      EXPECT_NE(m.to, m.from);
      EXPECT_EQ(kind[m.dim], FeatureColumns::kBlocked);
    }
  }
  // One rank: nothing moves.
  const ScreeningPlan one = plan_screening({1, 2, 3}, std::vector<uint8_t>(4, 1), 1);
  EXPECT_TRUE(one.moves.empty());
}

TEST(DimPartition, RefinementPlanGivesEveryDimOneRankAndMovesFromItsScreener) {
  Rng rng(8);
  for (int trial = 0; trial < 40; ++trial) {
    const int size = 2 + static_cast<int>(rng.below(4));
    std::vector<int32_t> round;
    for (int32_t d = 0; d < 300; d += 1 + static_cast<int32_t>(rng.below(4))) round.push_back(d);
    const ScreeningPlan screening = plan_screening(round, std::vector<uint8_t>(300, FeatureColumns::kBlocked), size);
    std::vector<ScreenedCandidate> chosen;
    for (int i = 0; i < 32; ++i) {
      ScreenedCandidate c;
      c.dim = round[rng.below(round.size())];
      c.theta = static_cast<int32_t>(rng.below(8));
      c.gain = rng.uniform();
      c.above_fraction = static_cast<float>(rng.uniform());
      chosen.push_back(c);
    }
    const RefinementPlan plan = plan_refinement(chosen, screening, size);
    std::map<int32_t, int> screener(screening.screener.begin(), screening.screener.end());
    std::map<int32_t, int> refiner(plan.refiner.begin(), plan.refiner.end());
    EXPECT_EQ(refiner.size(), plan.refiner.size());  // one rank a dim
    EXPECT_TRUE(std::is_sorted(plan.refiner.begin(), plan.refiner.end()));
    for (const ScreenedCandidate& c : chosen) ASSERT_TRUE(refiner.count(c.dim));
    for (const ColumnMove& m : plan.moves) {
      EXPECT_EQ(m.from, screener.at(m.dim));
      EXPECT_EQ(m.to, refiner.at(m.dim));
      EXPECT_NE(m.from, m.to);
    }
    for (const auto& [d, r] : refiner) {
      if (r != screener.at(d)) {
        EXPECT_TRUE(std::any_of(plan.moves.begin(), plan.moves.end(), [&](const ColumnMove& m) { return m.dim == d; }));
      }
    }
  }
}

}  // namespace
}  // namespace lmb
