#include "train/boost/boost_model.h"

#include <cmath>
#include <filesystem>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/file_container.h"

namespace lmb {
namespace {

BoostModel two_stump_model() {
  BoostModel m;
  m.num_dims = 3;
  m.num_classes = 2;
  m.class_landmark = {10, 20};
  m.bias = {0.5, -0.25, 0.0};
  m.stumps.push_back({1, 4, 2.0, -1.0, {0, 2}});
  m.stumps.push_back({2, 0, -0.5, 0.25, {1}});
  return m;
}

TEST(BoostModel, ScoresFollowTheDefinition) {
  const BoostModel m = two_stump_model();
  const uint8_t v[3] = {9, 5, 0};  // dim 1 fires (5 > 4), dim 2 does not (0 > 0 false)
  double s[3];
  m.scores(v, s);
  EXPECT_DOUBLE_EQ(s[0], 0.5 + 2.0 - 1.0);
  EXPECT_DOUBLE_EQ(s[1], -0.25 + 0.25);
  EXPECT_DOUBLE_EQ(s[2], 0.0 + 1.0);
  for (int c = 0; c < 3; ++c) EXPECT_DOUBLE_EQ(m.score(v, c), s[c]);
  EXPECT_EQ(m.classify(v), 0);
  const uint8_t w[3] = {0, 0, 0};
  m.scores(w, s);
  EXPECT_DOUBLE_EQ(s[0], 0.5 - 1.0);
  EXPECT_DOUBLE_EQ(s[1], -0.25 + 0.25);
  EXPECT_DOUBLE_EQ(s[2], -1.0);
  EXPECT_EQ(m.classify(w), 1);
}

TEST(BoostModel, RoundTripsAndRejectsCorruption) {
  const BoostModel m = two_stump_model();
  const std::string bytes = serialize_boost_model(m);
  EXPECT_EQ(deserialize_boost_model(bytes), m);
  EXPECT_THROW(deserialize_boost_model(bytes.substr(0, bytes.size() - 3)), Error);
  // A huge class count must fail before allocating.
  std::string huge = bytes;
  huge[1 + 4 + 4] = static_cast<char>(0xFF);
  huge[1 + 4 + 4 + 6] = static_cast<char>(0x7F);
  EXPECT_THROW(deserialize_boost_model(huge), Error);
}

TEST(BoostModel, TrainedModelFileRecordsTheFeatureSpace) {
  const BoostModel m = two_stump_model();
  const auto path =
      std::filesystem::temp_directory_path() / ("lmb_boost_model_test_" + std::to_string(::getpid()) + ".bin");
  EXPECT_THROW(save_trained_model(path, m, synthetic_feature_space("synthetic:x", 4)), Error);  // 3 dims
  EXPECT_FALSE(std::filesystem::exists(path));
  save_trained_model(path, m, synthetic_feature_space("synthetic:x", 3));
  const TrainedModel t = load_trained_model(path);
  EXPECT_EQ(t.model, m);
  EXPECT_EQ(t.feature_space.synthetic, "synthetic:x");
  EXPECT_EQ(t.feature_space.num_dims, 3);

  // A model.bin of format version 1 (the BoostModel alone) is refused with what to do.
  write_container_file(path, "LMBBOOST", 1, serialize_boost_model(m));
  try {
    load_trained_model(path);
    FAIL() << "a version-1 model.bin was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              path.string() +
                  ": a model.bin of an older lboost (format version 1), which does not record the context "
                  "regions, vocabulary and map it was trained with, so export cannot prove they match; "
                  "retrain it (or export it with the lboost that trained it)");
  }
  std::filesystem::remove(path);
}

TEST(BoostModel, CheckRejectsNonFiniteAndUnsorted) {
  BoostModel m = two_stump_model();
  m.stumps[0].a = std::nan("");
  EXPECT_THROW(m.check(), Error);
  m = two_stump_model();
  m.stumps[0].classes = {2, 0};
  EXPECT_THROW(m.check(), Error);
  m = two_stump_model();
  m.bias[1] = INFINITY;
  EXPECT_THROW(m.check(), Error);
}

}  // namespace
}  // namespace lmb
