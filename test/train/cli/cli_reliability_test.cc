// The reliability contract of `lboost train`, `export` and `localize` on a real (tiny rendered)
// map: a model can only be exported with the regions, vocabulary and map it was trained with; a
// refused run leaves its folder as it was; a run folder has one trainer at a time; bad options and
// outputs fail at once with one line and exit status 1.
#include <sys/wait.h>
#include <unistd.h>

#include <H5Cpp.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/file_io.h"
#include "test/support/lboost_run.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

using test::expect_one_error;
using test::RunResult;
using test::slurp;

RunResult run(const std::string& args, const fs::path& dir, const std::string& prefix = "") {
  return test::run_lboost(args, dir, prefix);
}

// lboost's own error lines (mpirun adds its banner to stderr).
std::vector<std::string> lboost_lines(const std::string& err) {
  std::vector<std::string> lines;
  std::istringstream in(err);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("lboost", 0) == 0) lines.push_back(line);
  }
  return lines;
}

// Every file of a folder tree with its bytes: "the folder is exactly as it was".
std::map<std::string, std::string> snapshot(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string name = fs::relative(e.path(), dir).string();
    files[name] = e.is_regular_file() ? slurp(e.path()) : std::string("<folder>");
  }
  return files;
}

// A copy of `from` with one landmark moved by 1 cm: another map of the same size.
void write_moved_map(const fs::path& from, const fs::path& to) {
  fs::copy_file(from, to, fs::copy_options::overwrite_existing);
  H5::H5File file(to.string(), H5F_ACC_RDWR);
  H5::DataSet ds = file.openDataSet("/landmarks/position");
  hsize_t dims[2] = {0, 0};
  ds.getSpace().getSimpleExtentDims(dims);
  std::vector<double> p(dims[0] * dims[1]);
  ds.read(p.data(), H5::PredType::NATIVE_DOUBLE);
  for (double& v : p) v += 0.01;
  ds.write(p.data(), H5::PredType::NATIVE_DOUBLE);
}

// One trained run on the tiny world, shared by the tests: map, two vocabularies, run (8 rounds,
// regions seed 1) and its model.lbm.
class CliReliabilityTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const char* map = std::getenv("LMB_TINY_MAP");
    if (map == nullptr || !fs::exists(map)) return;
    dir_ = fs::temp_directory_path() / ("lmb_cli_reliability_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    map_ = map;
    const fs::path images = fs::path(map).parent_path() / "collection" / "images";
    const std::string common = " --words 16 --max-descriptors 20000 --images " + images.string();
    ok_ = run("vocab" + common + " --seed 7 --out " + (dir_ / "vocab.lbv").string(), dir_).exit_code == 0 &&
          run("vocab" + common + " --seed 8 --out " + (dir_ / "vocab2.lbv").string(), dir_).exit_code == 0;
    const RunResult t = run(train_args() + " --out " + (dir_ / "run").string(), dir_);
    ok_ = ok_ && t.exit_code == 0;
    if (!ok_) std::fprintf(stderr, "setup failed: %s\n", t.err.c_str());
    ok_ = ok_ && run(export_args() + " --out " + (dir_ / "model.lbm").string(), dir_).exit_code == 0;
    write_moved_map(map_, dir_ / "moved_map.h5");
  }
  static void TearDownTestSuite() {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  void SetUp() override {
    if (map_.empty()) GTEST_SKIP() << "LMB_TINY_MAP (a map.h5 of `lboost world --preset tiny`) is not available";
    ASSERT_TRUE(ok_) << "the shared run could not be made";
  }
  static std::string train_args(const std::string& vocab = "vocab.lbv") {
    return "train --map " + map_.string() + " --vocab " + (dir_ / vocab).string() +
           " --rounds 8 --dims-per-round 64 --checkpoint-interval 4 --calibration-folds 0";
  }
  static std::string export_args(const std::string& vocab = "vocab.lbv", const std::string& run_dir = "run") {
    return "export --run " + (dir_ / run_dir).string() + " --map " + map_.string() + " --vocab " +
           (dir_ / vocab).string();
  }
  static fs::path dir_;
  static fs::path map_;
  static bool ok_;
};
fs::path CliReliabilityTest::dir_;
fs::path CliReliabilityTest::map_;
bool CliReliabilityTest::ok_ = false;

// Export refuses regions other than the run's: `--region-seed 2` on a seed-1 run would build a model
// whose P@1 is halved.
TEST_F(CliReliabilityTest, ExportRefusesOtherRegions) {
  const fs::path out = dir_ / "other_regions.lbm";
  expect_one_error(run(export_args() + " --region-seed 2 --out " + out.string(), dir_), "export",
                   "was trained with 1000 regions of seed 1, not 1000 of seed 2");
  expect_one_error(run(export_args() + " --regions 999 --out " + out.string(), dir_), "export",
                   "was trained with 1000 regions of seed 1, not 999 of seed 1");
  EXPECT_FALSE(fs::exists(out));
  // The right values are accepted (they are optional: the model records them) and change nothing.
  ASSERT_EQ(run(export_args() + " --region-seed 1 --regions 1000 --out " + out.string(), dir_).exit_code, 0);
  EXPECT_EQ(slurp(out), slurp(dir_ / "model.lbm"));
}

TEST_F(CliReliabilityTest, ExportRefusesAnotherVocabularyOrMap) {
  const fs::path out = dir_ / "other.lbm";
  expect_one_error(
      run(export_args("vocab2.lbv") + " --out " + out.string(), dir_), "export",
      "was not trained with the vocabulary " + (dir_ / "vocab2.lbv").string() + ": the vocabulary differs");
  const std::string moved = (dir_ / "moved_map.h5").string();
  expect_one_error(run("export --run " + (dir_ / "run").string() + " --map " + moved + " --vocab " +
                           (dir_ / "vocab.lbv").string() + " --out " + out.string(),
                       dir_),
                   "export", "was not trained on the map " + moved + ": the map differs");
  EXPECT_FALSE(fs::exists(out));
}

// A resume refused for another config leaves config.toml (which export reads) as it was.
TEST_F(CliReliabilityTest, RefusedResumeLeavesTheRunFolderExactlyAsItWas) {
  const fs::path run_dir = dir_ / "run";
  const auto before = snapshot(run_dir);
  write_file_atomically(dir_ / "seed2.toml", "[regions]\nseed = 2\n");
  expect_one_error(
      run(train_args() + " --config " + (dir_ / "seed2.toml").string() + " --out " + run_dir.string(), dir_), "train",
      "the config differs from the checkpoint's in regions.seed (checkpoint 1, now 2)");
  EXPECT_EQ(snapshot(run_dir), before);
  // Another vocabulary: the config agrees, the feature space does not (found after loading).
  expect_one_error(run(train_args("vocab2.lbv") + " --out " + run_dir.string(), dir_), "train",
                   "cannot resume: the vocabulary differs");
  EXPECT_EQ(snapshot(run_dir), before);
  // Export still builds the model of training.
  const fs::path out = dir_ / "again.lbm";
  ASSERT_EQ(run(export_args() + " --out " + out.string(), dir_).exit_code, 0);
  EXPECT_EQ(slurp(out), slurp(dir_ / "model.lbm"));
}

// Context augmentation (docs/matching.md) is deterministic for its seed and gives the
// same model on 1, 2 and 3 ranks; its noise is measured on the map and recorded.
TEST_F(CliReliabilityTest, AugmentedTrainingIsTheSameModelOnOneTwoAndThreeRanks) {
  const std::string args = train_args() + " --augment-copies 2 --checkpoint-minutes 0 --out ";
  const fs::path one = dir_ / "aug1", two = dir_ / "aug2", three = dir_ / "aug3";
  ASSERT_EQ(run(args + one.string(), dir_).exit_code, 0);
  ASSERT_EQ(run(args + two.string(), dir_, std::string(LMB_MPIEXEC) + " -n 2 ").exit_code, 0);
  ASSERT_EQ(run(args + three.string(), dir_, std::string(LMB_MPIEXEC) + " -n 3 ").exit_code, 0);
  const std::string model = slurp(one / "model.bin");
  EXPECT_EQ(slurp(two / "model.bin"), model);
  EXPECT_EQ(slurp(three / "model.bin"), model);
  EXPECT_NE(slurp(dir_ / "run" / "model.bin"), model);  // the augmented samples changed the training
  // Resumed on 2 ranks from the round-4 checkpoint (the model and every later checkpoint removed):
  // the copies are made again, the same model.
  fs::remove(two / "model.bin");
  for (const auto& e : fs::directory_iterator(two / "checkpoints")) {
    if (e.path().filename() != "ckpt-0000004.h5") fs::remove(e.path());
  }
  ASSERT_TRUE(fs::exists(two / "checkpoints" / "ckpt-0000004.h5"));
  const RunResult resumed = run(args + two.string(), dir_, std::string(LMB_MPIEXEC) + " -n 2 ");
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  EXPECT_NE(slurp(two / "log.txt").find("resumed from"), std::string::npos);
  EXPECT_EQ(slurp(two / "model.bin"), model);
  const std::string config = slurp(one / "config.toml");
  EXPECT_NE(config.find("[augment]"), std::string::npos) << config;
  const std::string summary = slurp(one / "summary.json");
  EXPECT_NE(summary.find("\"augment\""), std::string::npos) << summary;
  const std::string log = slurp(one / "log.txt");
  EXPECT_NE(log.find("map noise: detector repeatability"), std::string::npos) << log;
  EXPECT_NE(log.find("augmented samples"), std::string::npos) << log;
  // Another augmentation seed: another model.
  write_file_atomically(dir_ / "aug_seed.toml", "[augment]\nseed = 2\n");
  const fs::path other = dir_ / "aug_seed2";
  ASSERT_EQ(run(args + other.string() + " --config " + (dir_ / "aug_seed.toml").string(), dir_).exit_code, 0);
  EXPECT_NE(slurp(other / "model.bin"), model);
}

// A failed train leaves no config.toml and no empty log.txt behind.
TEST_F(CliReliabilityTest, FailedTrainLeavesNothingBehind) {
  write_file_atomically(dir_ / "not_a_map.h5", "plain text\n");
  const fs::path run_dir = dir_ / "failed_run";
  expect_one_error(run("train --map " + (dir_ / "not_a_map.h5").string() + " --vocab " + (dir_ / "vocab.lbv").string() +
                           " --out " + run_dir.string(),
                       dir_),
                   "train", "not_a_map.h5: not an HDF5 file");
  EXPECT_FALSE(fs::exists(run_dir));
  // An existing empty folder stays empty.
  fs::create_directories(run_dir);
  EXPECT_EQ(run("train --map " + (dir_ / "not_a_map.h5").string() + " --vocab " + (dir_ / "vocab.lbv").string() +
                    " --out " + run_dir.string(),
                dir_)
                .exit_code,
            1);
  EXPECT_TRUE(fs::is_empty(run_dir));
}

// A region count within its range (1..1048576) can ask for more memory than the machine has: refused
// before allocating, naming the key, its value, the bytes needed and the machine's memory; with
// MPI ranks the same single line.
TEST_F(CliReliabilityTest, RegionCountsBeyondTheMachinesMemoryAreRefused) {
  write_file_atomically(dir_ / "huge_regions.toml", "[regions]\nnum_regions = 1048576\n");
  const fs::path run_dir = dir_ / "huge_regions_run";
  const std::string args =
      train_args() + " --config " + (dir_ / "huge_regions.toml").string() + " --out " + run_dir.string();
  const std::string needle =
      (dir_ / "huge_regions.toml").string() + ": regions.num_regions = 1048576: the training features would need ";
  for (const std::string& prefix : {std::string(), std::string(LMB_MPIEXEC) + " -n 2 "}) {
    SCOPED_TRACE(prefix);
    const RunResult r = run(args, dir_, prefix);
    const auto lines = lboost_lines(r.err);
    ASSERT_EQ(lines.size(), 1u) << r.err;
    EXPECT_NE(r.exit_code, 0) << r.err;
    EXPECT_NE(lines[0].find("lboost train: error: " + needle), std::string::npos) << r.err;
    EXPECT_NE(lines[0].find(" regions x 16 words + 512 descriptor bits"), std::string::npos) << r.err;
    EXPECT_NE(lines[0].find("), more than the memory of this machine ("), std::string::npos) << r.err;
    EXPECT_NE(lines[0].find(" bytes available, "), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("bad_alloc"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(run_dir));
  }
}

// A second trainer on the same --out fails at once.
TEST_F(CliReliabilityTest, SecondTrainerFailsAtOnce) {
  const fs::path run_dir = dir_ / "locked_run";
  fs::create_directories(run_dir);
  FileLock held;
  ASSERT_EQ(held.try_lock(run_dir / ".train.lock"), FileLock::Status::kLocked);
  const auto before = snapshot(run_dir);
  const RunResult r = run(train_args() + " --out " + run_dir.string(), dir_);
  expect_one_error(r, "train", "another lboost train is using this run folder (pid " + std::to_string(::getpid()));
  EXPECT_EQ(snapshot(run_dir), before);
  // With MPI ranks: rank 0 holds the lock; every rank stops, one lboost line.
  const RunResult m = run(train_args() + " --out " + run_dir.string(), dir_, std::string(LMB_MPIEXEC) + " -n 2 ");
  EXPECT_NE(m.exit_code, 0);
  const auto lines = lboost_lines(m.err);
  ASSERT_EQ(lines.size(), 1u) << m.err;
  EXPECT_NE(lines[0].find("another lboost train is using this run folder"), std::string::npos) << m.err;
  held.unlock();
  // A real pair: the second of two trainers started on one folder fails while the first runs.
  const fs::path pair_dir = dir_ / "pair_run";
  const std::string first = std::string(LMB_LBOOST) + " train --synthetic small --rounds 100000 --dims-per-round 64 " +
                            "--checkpoint-interval 0 --out " + pair_dir.string() + " > /dev/null 2>&1 & echo $! > " +
                            (dir_ / "first.pid").string();
  ASSERT_EQ(std::system(first.c_str()), 0);
  // Accepted (so locked) once it logs its first round.
  for (int i = 0; i < 1200 && !fs::exists(pair_dir / "metrics.jsonl"); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(fs::exists(pair_dir / "metrics.jsonl")) << "the first trainer did not start";
  const RunResult second = run("train --synthetic small --rounds 10 --out " + pair_dir.string(), dir_);
  const std::string kill = "kill -KILL $(cat " + (dir_ / "first.pid").string() + ")";
  EXPECT_EQ(std::system(kill.c_str()), 0);
  expect_one_error(second, "train", "another lboost train is using this run folder");
}

// Option errors are one line with status 1.
TEST_F(CliReliabilityTest, BadOptionsFailWithOneLine) {
  expect_one_error(run(train_args() + " --seed -1 --out " + (dir_ / "seed_run").string(), dir_), "train",
                   "--seed: '-1' must be an integer in 0..9223372036854775807");
  EXPECT_FALSE(fs::exists(dir_ / "seed_run"));
  expect_one_error(run("train --rounds abc --out x", dir_), "train", "--rounds");
  expect_one_error(run("train --synthetic small --no-such-option 3 --out x", dir_), "train", "--no-such-option");
  expect_one_error(run("export --map " + map_.string(), dir_), "export", "is required");
  expect_one_error(run("inspect " + map_.string() + " --threads 0", dir_), "inspect",
                   "--threads = 0 must be in 1..256");
  expect_one_error(
      run("map --collection " + (dir_ / "none").string() + " --pair-distance -1 --out " + (dir_ / "m.h5").string(),
          dir_),
      "map", "max_center_distance must be finite and >= 0");
  const RunResult help = run("train --help", dir_);
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.out.find("--out"), std::string::npos);
}

// `map` reports an unwritable --out before the mapping run, not after it.
TEST_F(CliReliabilityTest, UnwritableOutputsFailBeforeTheWork) {
  write_file_atomically(dir_ / "a_file", "x");
  const std::string bad = (dir_ / "a_file" / "out").string();
  const fs::path collection = map_.parent_path() / "collection";
  const RunResult m = run("map --collection " + collection.string() + " --out " + bad, dir_);
  expect_one_error(m, "map", bad);
  EXPECT_EQ(m.out.find("map:"), std::string::npos) << "mapped before failing: " << m.out;
  expect_one_error(run(export_args() + " --out " + bad, dir_), "export", bad);
  expect_one_error(
      run("localize --model " + (dir_ / "model.lbm").string() + " --map " + map_.string() + " --out " + bad, dir_),
      "localize", bad);
  expect_one_error(run("train --synthetic small --out " + bad, dir_), "train", bad);
}

// A folder as the model, and a model of another map.
TEST_F(CliReliabilityTest, LocalizeRefusesAFolderOrAnotherMapsModel) {
  const fs::path out = dir_ / "poses.json";
  expect_one_error(
      run("localize --model " + dir_.string() + " --map " + map_.string() + " --out " + out.string(), dir_), "localize",
      dir_.string() + ": is a folder, not a file");
  expect_one_error(run("localize --model " + (dir_ / "model.lbm").string() + " --map " +
                           (dir_ / "moved_map.h5").string() + " --out " + out.string(),
                       dir_),
                   "localize", "(the model was trained on another map)");
  EXPECT_FALSE(fs::exists(out));
  ASSERT_EQ(
      run("localize --model " + (dir_ / "model.lbm").string() + " --map " + map_.string() + " --out " + out.string(),
          dir_)
          .exit_code,
      0);
  EXPECT_TRUE(fs::file_size(out) > 0);
}

}  // namespace
}  // namespace lmb
