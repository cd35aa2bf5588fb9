#include "train/boost/train_config.h"

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

TEST(TrainConfig, FileOverridesDefaultsAndRoundTrips) {
  TrainConfig c;
  apply_train_config_toml(
      "[boost]\nnum_rounds = 300\nexclusion_radius = 0.5\nscreening_step = true\n"
      "[training_set]\ntop_k_landmarks = 900\n[regions]\nnum_regions = 64\n[features]\nthreads = 2\n",
      "cfg.toml", &c);
  EXPECT_EQ(c.boost.num_rounds, 300);
  EXPECT_DOUBLE_EQ(c.boost.exclusion_radius, 0.5);
  EXPECT_TRUE(c.boost.screening_step);
  EXPECT_EQ(c.boost.dims_per_round, BoostOptions().dims_per_round);
  EXPECT_EQ(c.training_set.top_k_landmarks, 900);
  EXPECT_EQ(c.regions.num_regions, 64);
  EXPECT_EQ(c.feature_threads, 2);
  TrainConfig d;
  apply_train_config_toml(train_config_toml(c), "effective", &d);
  EXPECT_EQ(train_config_toml(d), train_config_toml(c));
  EXPECT_EQ(d.boost.num_rounds, 300);
  EXPECT_EQ(d.regions.num_regions, 64);
}

TEST(TrainConfig, RejectsUnknownKeysWrongTypesAndSyntax) {
  TrainConfig c;
  auto message = [&](const std::string& text) {
    try {
      apply_train_config_toml(text, "cfg.toml", &c);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("[boost]\nnum_round = 3\n").find("boost.num_round"), std::string::npos);
  EXPECT_NE(message("[bost]\n").find("[bost]"), std::string::npos);
  EXPECT_NE(message("[boost]\nnum_rounds = \"many\"\n").find("integer"), std::string::npos);
  EXPECT_NE(message("[boost]\nnum_rounds = 1e99\n").find("integer"), std::string::npos);
  // Regression (found by test/fuzz/fuzz_train_config under UBSan): a float beyond the int64 range
  // for an integer key was cast to int64 inside toml++ before any range check.
  EXPECT_EQ(message("[boost]\nnum_rounds = 1e37\n"), "cfg.toml: boost.num_rounds: expected an integer");
  EXPECT_NE(message("[boost]\nnum_rounds = 99999999999\n").find("out of range"), std::string::npos);
  EXPECT_NE(message("[boost\n").find("cfg.toml"), std::string::npos);
  TrainConfig zero;
  apply_train_config_toml("[boost]\nnum_rounds = 0\n", "cfg.toml", &zero);
  EXPECT_THROW(zero.check(), Error);
}

}  // namespace
}  // namespace lmb
