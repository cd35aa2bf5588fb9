// Candidate thresholds, screening kinds and lent columns.
#include "train/boost/feature_columns.h"

#include <set>

#include <gtest/gtest.h>

#include "common/error.h"
#include "test/train/boost/learner_parts.h"

namespace lmb {
namespace {

using test::make_parts;

TEST(FeatureColumns, ThresholdsKindsAndLentColumns) {
  const auto p = make_parts(8);
  const FeatureMatrix& f = p->problem.features;
  for (int32_t d = 0; d < f.num_dims; ++d) {
    const FeatureColumns::Layout& layout = *p->columns->get(d, "test").layout;
    std::set<int> values(f.column(d), f.column(d) + f.num_samples);
    EXPECT_LE(layout.thresholds.size(), 8u);
    EXPECT_EQ(layout.thresholds.empty(), values.size() < 2);
    if (!layout.thresholds.empty()) {  // smallest bin first
      EXPECT_EQ(layout.thresholds.front(), *values.begin());
    }
    for (size_t t = 0; t < layout.thresholds.size(); ++t) {
      EXPECT_TRUE(values.count(layout.thresholds[t]));
      EXPECT_NE(layout.thresholds[t], *values.rbegin());  // never the largest bin
      EXPECT_EQ(static_cast<size_t>(layout.bucket[layout.thresholds[t] + 1]), t + 1);
    }
  }
  // A column packed on one side and lent on another reads back the same.
  FeatureMatrix odd;
  odd.num_samples = f.num_samples;
  odd.num_dims = f.num_dims;
  odd.dims = {1, 3};
  for (int32_t d : odd.dims) odd.data.insert(odd.data.end(), f.column(d), f.column(d) + f.num_samples);
  FeatureColumns here(odd, p->options.screening);
  EXPECT_FALSE(here.find(4).column);
  here.lend(4, p->columns->pack(4));
  const FeatureColumns::Ref lent = here.get(4, "test");
  EXPECT_EQ(std::vector<uint8_t>(lent.column, lent.column + f.num_samples),
            std::vector<uint8_t>(f.column(4), f.column(4) + f.num_samples));
  EXPECT_EQ(lent.layout->thresholds, p->columns->get(4, "test").layout->thresholds);
  std::vector<uint8_t> a, b;
  here.above(4, lent.layout->thresholds[0], &a);
  p->columns->above(4, lent.layout->thresholds[0], &b);
  EXPECT_EQ(a, b);
  here.drop_lent();
  EXPECT_FALSE(here.find(4).column);
  EXPECT_THROW(here.lend(4, std::vector<uint8_t>(7, 0)), Error);
}

}  // namespace
}  // namespace lmb
