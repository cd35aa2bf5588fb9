// The column screener against brute-force sums over the entries, and its blocked pass against
// its column passes, bit for bit.
#include "train/boost/column_screener.h"

#include <algorithm>

#include <gtest/gtest.h>

#include "common/error.h"
#include "test/train/boost/learner_parts.h"

namespace lmb {
namespace {

using test::make_parts;

using test::brute_force_above;

TEST(ColumnScreener, CollectedSumsEqualTheEntriesAboveEachThreshold) {
  const auto p = make_parts(0);  // every distinct bin a threshold
  ColumnScreener screener(*p->entries);
  std::vector<int64_t> pos, neg;
  for (int32_t dim : {0, 5, p->problem.context_dims, p->problem.features.num_dims - 1}) {
    const FeatureColumns::Ref ref = p->columns->get(dim, "test");
    if (ref.layout->thresholds.empty()) continue;
    screener.collect_sums(ref);
    const std::vector<int32_t>& touched = screener.touched();
    const size_t m = touched.size();
    for (size_t t = 0; t < ref.layout->thresholds.size(); ++t) {
      brute_force_above(*p, dim, ref.layout->thresholds[t], &pos, &neg);
      for (size_t j = 0; j < m; ++j) {
        EXPECT_EQ(screener.positive_above()[t * m + j], pos[touched[j]]) << "dim " << dim << " t " << t;
        EXPECT_EQ(screener.negative_above()[t * m + j], neg[touched[j]]);
      }
      // The classes left out have no weight above the smallest threshold.
      if (t == 0) {
        for (int32_t c = 0; c < p->entries->num_classes(); ++c) {
          if (!std::binary_search(touched.begin(), touched.end(), c)) {
            EXPECT_EQ(pos[c] + neg[c], 0);
          }
        }
      }
    }
  }
}

TEST(ColumnScreener, BlockedPassEqualsColumnPassesBitForBit) {
  for (int32_t thresholds : {1, 4, 9, 15}) {
    const auto p = make_parts(thresholds);
    ColumnScreener screener(*p->entries);
    std::vector<FeatureColumns::Ref> refs;
    for (int32_t d = 0; d < p->problem.features.num_dims && refs.size() < 7; d += 3) {
      const FeatureColumns::Ref ref = p->columns->get(d, "test");
      if (p->columns->kind(*ref.layout) == FeatureColumns::kBlocked) refs.push_back(ref);
    }
    ASSERT_EQ(refs.size(), 7u);
    double gains[ColumnScreener::kBlockDims * 16];
    screener.screen_block(refs.data(), static_cast<int32_t>(refs.size()), gains);
    std::vector<double> column;
    int positive = 0;
    for (size_t k = 0; k < refs.size(); ++k) {
      screener.screen_column(refs[k], false, &column);
      ASSERT_EQ(column.size(), refs[k].layout->thresholds.size());
      for (size_t t = 0; t < column.size(); ++t) {
        EXPECT_EQ(gains[k * 16 + t], column[t]) << thresholds << " thresholds, dim " << refs[k].dim << " t " << t;
        positive += column[t] > 0;
      }
    }
    EXPECT_GT(positive, 0);
  }
}

}  // namespace
}  // namespace lmb
