#include "train/checkpoint/checkpoint_h5.h"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include <H5Cpp.h>
#include <gtest/gtest.h>

#include "common/error.h"
#include "common/feature_space.h"
#include "train/boost/stump_learner.h"
#include "train/boost/synthetic_problem.h"
#include "train/boost/train_config.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

class CheckpointTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lmb_ckpt_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    SyntheticBoostOptions o;
    o.num_classes = 20;
    problem_ = make_synthetic_boost_problem(o);
    config_.boost.num_rounds = 12;
    config_.boost.dims_per_round = 64;
    config_.boost.mining.interval = 4;
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A checkpoint after `rounds` rounds of a real learner.
  Checkpoint make(int32_t rounds) {
    SerialStumpLearner learner(problem_.features, problem_.set, config_.boost);
    for (int32_t r = 0; r < rounds; ++r) learner.run_round();
    Checkpoint ck;
    ck.rounds = rounds;
    ck.seed = config_.boost.seed;
    ck.ranks = 2;
    ck.config = train_config_toml(config_);
    ck.data = "synthetic:test";
    ck.feature_space = synthetic_feature_space(ck.data, problem_.features.num_dims);
    ck.state = learner.save_state();
    return ck;
  }

  fs::path dir_;
  SyntheticBoostProblem problem_;
  TrainConfig config_;
};

void expect_same_state(const LearnerState& a, const LearnerState& b) {
  EXPECT_TRUE(a.model == b.model);
  EXPECT_EQ(a.entry_sample, b.entry_sample);
  EXPECT_EQ(a.entry_code, b.entry_code);
  EXPECT_EQ(a.entry_weight, b.entry_weight);
  EXPECT_EQ(a.weight_exponent, b.weight_exponent);
  EXPECT_EQ(a.tracked_samples, b.tracked_samples);
  EXPECT_EQ(a.num_validation_rows, b.num_validation_rows);
  EXPECT_EQ(a.tracked_scores, b.tracked_scores);
  EXPECT_EQ(a.class_offset, b.class_offset);
  EXPECT_EQ(a.negative_unit, b.negative_unit);
  EXPECT_EQ(a.last_validation, b.last_validation);
}

TEST_F(CheckpointTest, RoundTripsExactlyAndResumesBitIdentically) {
  const Checkpoint ck = make(5);
  const fs::path path = dir_ / "a.h5";
  write_checkpoint(path, ck);
  const Checkpoint back = read_checkpoint(path);
  EXPECT_EQ(back.rounds, 5);
  EXPECT_EQ(back.seed, ck.seed);
  EXPECT_EQ(back.ranks, 2);
  EXPECT_EQ(back.config, ck.config);
  EXPECT_EQ(back.data, ck.data);
  EXPECT_EQ(back.feature_space.synthetic, "synthetic:test");
  EXPECT_EQ(back.feature_space.num_dims, problem_.features.num_dims);
  expect_same_state(back.state, ck.state);
  // No temporary file is left behind.
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir_)) files += e.is_regular_file();
  EXPECT_EQ(files, 1);

  // Restored and continued == uninterrupted (mining at rounds 4 and 8 on both sides).
  SerialStumpLearner resumed(problem_.features, problem_.set, config_.boost);
  resumed.restore_state(back.state);
  resumed.train();
  SerialStumpLearner straight(problem_.features, problem_.set, config_.boost);
  straight.train();
  EXPECT_TRUE(resumed.model() == straight.model());
  expect_same_state(resumed.save_state(), straight.save_state());
}

TEST_F(CheckpointTest, TornOrCorruptNewestFallsBackToThePreviousOne) {
  const CheckpointDir dir(dir_);
  dir.write(make(3), 5);
  dir.write(make(6), 5);
  dir.write(make(9), 5);
  ASSERT_EQ(dir.list().size(), 3u);
  // Torn: the newest cut in half.
  const fs::path newest = dir.path_for(9);
  fs::resize_file(newest, fs::file_size(newest) / 2);
  std::vector<std::string> skipped;
  auto ck = dir.newest_valid(
      [&](const fs::path& p, const std::string& why) { skipped.push_back(p.filename().string() + ": " + why); });
  ASSERT_TRUE(ck.has_value());
  EXPECT_EQ(ck->rounds, 6);
  ASSERT_EQ(skipped.size(), 1u);
  EXPECT_NE(skipped[0].find("ckpt-0000009.h5"), std::string::npos) << skipped[0];

  // Corrupt: one flipped byte inside the entry weights of the (now) newest valid file; the CRC
  // (or HDF5) catches it and the one before is used.
  const fs::path six = dir.path_for(6);
  {
    const auto size = fs::file_size(six);
    std::fstream f(six, std::ios::in | std::ios::out | std::ios::binary);
    std::vector<char> bytes(size);
    f.read(bytes.data(), static_cast<std::streamsize>(size));
    // Flip a byte of the largest dataset (tracked scores): the last quarter of the file is data.
    const size_t at = size - size / 8;
    bytes[at] = static_cast<char>(bytes[at] ^ 0x5A);
    f.seekp(0);
    f.write(bytes.data(), static_cast<std::streamsize>(size));
  }
  skipped.clear();
  ck = dir.newest_valid([&](const fs::path& p, const std::string& why) { skipped.push_back(why); });
  ASSERT_TRUE(ck.has_value());
  EXPECT_EQ(ck->rounds, 3);
  ASSERT_EQ(skipped.size(), 2u);
  EXPECT_THROW(read_checkpoint(six), Error);
}

TEST_F(CheckpointTest, KeepsTheNewestK) {
  const CheckpointDir dir(dir_);
  for (int32_t r : {2, 4, 6, 8}) dir.write(make(r), 2);
  const auto files = dir.list();
  ASSERT_EQ(files.size(), 2u);
  EXPECT_EQ(files[0], dir.path_for(8));
  EXPECT_EQ(files[1], dir.path_for(6));
}

TEST_F(CheckpointTest, RemovesTemporariesOfKilledWritersOnly) {
  // A writer killed mid-write leaves ".ckpt-N.h5.tmp-PID"; the next write deletes it when no
  // process PID runs here, and keeps those of running processes (our own, pid 1).
  const CheckpointDir dir(dir_);
  dir.write(make(2), 3);
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  ASSERT_GT(child, 0);
  ASSERT_EQ(::waitpid(child, nullptr, 0), child);  // reaped: its pid runs nothing now
  auto touch = [&](const std::string& name) {
    std::ofstream(dir.folder() / name) << "partial";
    return dir.folder() / name;
  };
  const auto dead = touch(".ckpt-0000004.h5.tmp-" + std::to_string(child));
  const auto own = touch(".ckpt-0000099.h5.tmp-" + std::to_string(::getpid()));  // not the name written
  const auto init = touch(".ckpt-0000004.h5.tmp-1");
  const auto other = touch("notes.tmp-" + std::to_string(child));
  dir.write(make(4), 3);
  EXPECT_FALSE(std::filesystem::exists(dead));
  EXPECT_TRUE(std::filesystem::exists(own));
  EXPECT_TRUE(std::filesystem::exists(init));
  EXPECT_TRUE(std::filesystem::exists(other));
  EXPECT_EQ(dir.list().size(), 2u);
}

TEST_F(CheckpointTest, ConfigDifferenceNamesTheSetting) {
  const std::string base = train_config_toml(config_);
  TrainConfig other = config_;
  EXPECT_EQ(config_difference(base, train_config_toml(other)), "");
  other.boost.num_rounds = 99;  // a run may be extended
  other.feature_threads = 2;
  other.checkpoint_interval = 7;
  EXPECT_EQ(config_difference(base, train_config_toml(other)), "");
  EXPECT_EQ(config_hash(base), config_hash(train_config_toml(other)));
  other.boost.dims_per_round = 32;
  EXPECT_EQ(config_difference(base, train_config_toml(other)), "boost.dims_per_round (checkpoint 64, now 32)");
  EXPECT_NE(config_hash(base), config_hash(train_config_toml(other)));
  other = config_;
  other.training_set.seed = 5;
  EXPECT_EQ(config_difference(base, train_config_toml(other)), "training_set.seed (checkpoint 1, now 5)");
}

TEST_F(CheckpointTest, RejectsMissingAndForeignFiles) {
  EXPECT_THROW(read_checkpoint(dir_ / "none.h5"), Error);
  const fs::path text = dir_ / "ckpt-0000001.h5";
  std::ofstream(text) << "not hdf5";
  EXPECT_THROW(read_checkpoint(text), Error);
  EXPECT_FALSE(CheckpointDir(dir_).newest_valid({}).has_value());  // no checkpoints/ folder
}

TEST_F(CheckpointTest, RecordsTheFeatureSpaceOfAMap) {
  Checkpoint ck = make(2);
  const ContextRegions regions(ContextRegionOptions{.num_regions = 3});
  std::vector<uint8_t> words(16 * 8);
  for (size_t i = 0; i < words.size(); ++i) words[i] = static_cast<uint8_t>(i * 37);
  LandmarkMap map;
  map.descriptor_bytes = 8;
  ck.feature_space = map_feature_space(regions, Vocabulary(8, words), map);
  // The learner's problem has another dimension: the writer refuses the mismatch.
  EXPECT_THROW(write_checkpoint(dir_ / "x.h5", ck), Error);
  EXPECT_FALSE(fs::exists(dir_ / "x.h5"));
  ck.state.model.num_dims = ck.feature_space.num_dims;
  for (SharedStump& s : ck.state.model.stumps) s.dim = std::min(s.dim, ck.feature_space.num_dims - 1);
  write_checkpoint(dir_ / "x.h5", ck);
  const Checkpoint back = read_checkpoint(dir_ / "x.h5");
  EXPECT_EQ(feature_space_difference(ck.feature_space, back.feature_space), "");
  EXPECT_TRUE(back.feature_space.regions == regions);
}

// A checkpoint of format version 1 (no feature space) is refused, never skipped for an older one:
// resuming from an older checkpoint would silently throw rounds away.
TEST_F(CheckpointTest, OldFormatVersionIsRefusedNotSkipped) {
  const CheckpointDir dir(dir_);
  dir.write(make(3), 5);
  const fs::path newest = dir.write(make(6), 5);
  {
    H5::H5File file(newest.string(), H5F_ACC_RDWR);
    const int32_t one = 1;
    file.openAttribute("format_version").write(H5::PredType::NATIVE_INT32, &one);
  }
  try {
    dir.newest_valid({});
    FAIL() << "a version-1 checkpoint was skipped";
  } catch (const CheckpointVersionError& e) {
    EXPECT_EQ(std::string(e.what()),
              newest.string() +
                  ": written by an older lboost (checkpoint format version 1), which does not record "
                  "the context regions, vocabulary and map it was trained with; finish the run with "
                  "the lboost that started it, or train into a new --out folder");
  }
}

TEST_F(CheckpointTest, RestoreRejectsAStateOfAnotherProblem) {
  Checkpoint ck = make(2);
  SyntheticBoostOptions o;
  o.num_classes = 30;
  const SyntheticBoostProblem other = make_synthetic_boost_problem(o);
  SerialStumpLearner learner(other.features, other.set, config_.boost);
  EXPECT_THROW(learner.restore_state(ck.state), Error);
}

}  // namespace
}  // namespace lmb
