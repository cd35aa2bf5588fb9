#include "train/boost/boost_bench.h"

#include <gtest/gtest.h>

namespace lmb {
namespace {

TEST(BoostBench, RunsASmallShape) {
  BoostBenchOptions o;
  o.data = SyntheticBoostOptions();
  o.boost.dims_per_round = 50;
  o.rounds = 3;
  const BoostBenchResult r = run_boost_bench(o);
  EXPECT_EQ(r.num_classes, o.data.num_classes);
  EXPECT_GT(r.num_entries, int64_t{o.data.num_classes} * 10);
  EXPECT_GT(r.seconds_per_round, 0.0);
  EXPECT_GT(r.peak_rss_mb, 0.0);
  // The phases are disjoint parts of the rounds' time: each fraction in [0, 1], their sum at most 1
  // (the rest, e.g. mining, is not a phase; how much it is depends on the machine, so no bound).
  for (double f : {r.histogram_fraction, r.search_fraction, r.update_fraction, r.eval_fraction}) {
    EXPECT_GE(f, 0.0);
    EXPECT_LE(f, 1.0);
  }
  const double sum = r.histogram_fraction + r.search_fraction + r.update_fraction + r.eval_fraction;
  EXPECT_GT(sum, 0.0);
  EXPECT_LE(sum, 1.0 + 1e-9);
  EXPECT_NE(r.to_json().find("seconds_per_round"), std::string::npos);
}

}  // namespace
}  // namespace lmb
