#include "train/boost/boost_options.h"

#include <cmath>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

TEST(BoostOptions, DefaultsAreValid) {
  EXPECT_NO_THROW(BoostOptions().check());
  EXPECT_NO_THROW(BoostOptions().check(16896));
  EXPECT_NO_THROW(TrainingSetOptions().check());
}

TEST(BoostOptions, RejectsZeroRounds) {
  BoostOptions o;
  o.num_rounds = 0;
  try {
    o.check();
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("num_rounds"), std::string::npos);
  }
}

TEST(BoostOptions, RejectsMoreCandidateDimsThanDims) {
  BoostOptions o;
  o.dims_per_round = 501;
  EXPECT_NO_THROW(o.check());
  try {
    o.check(500);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("dims_per_round"), std::string::npos);
  }
}

TEST(BoostOptions, RejectsBadFields) {
  auto bad = [](auto mutate) {
    BoostOptions o;
    mutate(o);
    EXPECT_THROW(o.check(), Error);
  };
  bad([](BoostOptions& o) { o.dims_per_round = 0; });
  bad([](BoostOptions& o) { o.screening.max_thresholds = 256; });
  bad([](BoostOptions& o) { o.negatives.per_class = -1; });
  bad([](BoostOptions& o) { o.negatives.max_per_class = o.negatives.per_class - 1; });
  bad([](BoostOptions& o) { o.mining.interval = -1; });
  bad([](BoostOptions& o) { o.negatives.exclusion_radius = std::nan(""); });
  bad([](BoostOptions& o) { o.sharing.max_iterations = 0; });
  bad([](BoostOptions& o) { o.screening.refine_top = -1; });
  TrainingSetOptions t;
  t.validation_fraction = 1.0;
  EXPECT_THROW(t.check(), Error);
  t = TrainingSetOptions();
  t.top_k_landmarks = 0;
  EXPECT_THROW(t.check(), Error);
}

}  // namespace
}  // namespace lmb
