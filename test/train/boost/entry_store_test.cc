// The entry store against its formulas: exact fixed-point sums, both copies, the weight update.
#include "train/boost/entry_store.h"

#include <cmath>

#include <gtest/gtest.h>

#include "common/error.h"
#include "test/train/boost/learner_parts.h"

namespace lmb {
namespace {

using test::make_parts;

TEST(EntryStore, FixedPointSumsAreExactAndTheUpdateMatchesItsFormula) {
  const auto p = make_parts(8);
  const EntryStore& e = *p->entries;
  // Class totals are the sums of the fixed-point weights, each weight its stored one rounded.
  std::vector<int64_t> w(static_cast<size_t>(e.num_classes()), 0), y(w.size(), 0);
  int64_t total = 0;
  for (int64_t i = 0; i < e.size(); ++i) {
    const int64_t q = e.hot()[i].wq;
    EXPECT_EQ(q, std::llround(std::ldexp(e.stored_weight(i), e.quant_shift())));
    w[e.code(i) >> 1] += q;
    y[e.code(i) >> 1] += (e.code(i) & 1) ? -q : q;
    total += q;
  }
  EXPECT_EQ(w, e.class_w());
  EXPECT_EQ(y, e.class_y());
  EXPECT_LT(total, int64_t{1} << 52);
  // The class-major copy holds the same weights: positives, then negatives, by ascending sample.
  for (int32_t c = 0; c < e.num_classes(); ++c) {
    int64_t sum = 0;
    for (int64_t j = e.class_begin(c); j < e.class_begin(c + 1); ++j) {
      sum += e.class_wq()[j];
      if (j > e.class_begin(c) && j != e.class_negatives_begin(c)) {
        EXPECT_LT(e.class_sample()[j - 1], e.class_sample()[j]);
      }
    }
    EXPECT_EQ(sum, e.class_w()[c]);
  }
  // update(): w exp(-z h), and the squared error sum w (z - h)^2 before it.
  EntryStore copy = e;
  const std::vector<EntryStore::Entry> before = copy.entries();
  std::vector<uint8_t> above(static_cast<size_t>(copy.num_samples()));
  for (size_t s = 0; s < above.size(); ++s) above[s] = s % 3 == 0;
  std::vector<uint8_t> in_set(static_cast<size_t>(copy.num_classes()), 0);
  in_set[2] = in_set[5] = 1;
  std::vector<double> k(in_set.size());
  for (size_t c = 0; c < k.size(); ++c) k[c] = 0.01 * static_cast<double>(c) - 0.1;
  const EntryStore::UpdateSums sums = copy.update(above, in_set, 0.4, -0.2, k);
  const std::vector<EntryStore::Entry> after = copy.entries();
  ASSERT_EQ(before.size(), after.size());
  double squared_error = 0, cost = 0;
  for (size_t i = 0; i < before.size(); ++i) {
    const double h = in_set[before[i].cls] ? (above[before[i].sample] ? 0.4 : -0.2) : k[before[i].cls];
    squared_error += before[i].weight * (before[i].z - h) * (before[i].z - h);
    EXPECT_NEAR(after[i].weight, before[i].weight * std::exp(-before[i].z * h), 1e-12 * before[i].weight);
    cost += after[i].weight;
  }
  EXPECT_NEAR(sums.squared_error, squared_error, 1e-9 * squared_error);
  EXPECT_NEAR(sums.cost, cost, 1e-9 * cost);
  // save / restore round trip; a state out of order is refused.
  LearnerState st;
  copy.save(&st);
  EntryStore restored(copy.num_samples(), copy.num_classes());
  restored.check(st);
  restored.restore(st);
  EXPECT_EQ(restored.exp_loss(), copy.exp_loss());
  std::swap(st.entry_sample.front(), st.entry_sample.back());
  EXPECT_THROW(restored.check(st), Error);
}

}  // namespace
}  // namespace lmb
