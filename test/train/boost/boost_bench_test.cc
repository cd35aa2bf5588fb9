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
  EXPECT_NEAR(r.histogram_fraction + r.search_fraction + r.update_fraction + r.eval_fraction, 1.0, 0.2);
  EXPECT_NE(r.to_json().find("seconds_per_round"), std::string::npos);
}

}  // namespace
}  // namespace lmb
