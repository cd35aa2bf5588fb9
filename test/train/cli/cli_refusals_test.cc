// Refusals of lboost and lboost-bench that need no map, each one line naming what was refused:
// - every seed option means the same: a decimal integer in 0..2^63-1; anything else (a negative
//   number, 2^63 and above, hexadecimal, text) fails at parsing, naming the option. The largest seed
//   passes the parsing (the runs here then stop at an unknown or a missing required option, before
//   any work);
// - an image smaller than the detector takes, naming the image, its size and the minimum;
// - a failed allocation in `lboost train`, naming what was being allocated.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "test/support/lboost_run.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

using test::expect_one_error;
using test::RunResult;

class CliRefusalsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lmb_cli_refusals_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

// (program, command, option) of every seed option of lboost and lboost-bench.
struct SeedOption {
  std::string program, command, option;
};
const std::vector<SeedOption> kSeedOptions = {
    {"lboost", "world", "--seed"},
    {"lboost", "areas", "--seed"},
    {"lboost", "bundle", "--seed"},
    {"lboost", "vocab", "--seed"},
    {"lboost", "train", "--seed"},
    {"lboost", "export", "--region-seed"},
    {"lboost", "localize", "--seed"},
    {"lboost", "localize", "--prior-seed"},
    {"lboost", "eval", "--seed"},
    {"lboost", "eval", "--prior-seed"},
    {"lboost-bench", "context", "--seed"},
    {"lboost-bench", "context", "--region-seed"},
    {"lboost-bench", "infer", "--seed"},
    {"lboost-bench", "bundle", "--seed"},
    {"lboost-bench", "bundle", "--prior-seed"},
};

TEST_F(CliRefusalsTest, EverySeedOptionTakesZeroTo2Pow63Minus1) {
  for (const auto& [program, command, option] : kSeedOptions) {
    SCOPED_TRACE(program + " " + command + " " + option);
    const auto run = [&](const std::string& args) {
      return test::run_program(program == "lboost" ? LMB_LBOOST : LMB_LBOOST_BENCH, args, dir_);
    };
    for (const std::string& bad : std::vector<std::string>{"-1", "9223372036854775808", "18446744073709551615",
                                                           "99999999999999999999999", "0x10", "1e3", "abc", "1.5"}) {
      expect_one_error(run(command + " " + option + " " + bad), command,
                       option + ": '" + bad + "' must be an integer in 0..9223372036854775807 (see --help)", program);
    }
    for (const std::string& good : std::vector<std::string>{"0", "9223372036854775807", "0009223372036854775807"}) {
      // Parsed: what stops the run is another option (the unknown one, or a required one missing).
      const RunResult r = run(command + " " + option + " " + good + " --no-such-option");
      expect_one_error(r, command, "", program);
      EXPECT_EQ(r.err.find(option + ":"), std::string::npos) << r.err;
      EXPECT_EQ(r.err.find("Could not convert"), std::string::npos) << r.err;
      EXPECT_EQ(r.err.find("0..9223372036854775807"), std::string::npos) << r.err;
    }
  }
}

// An allocation that fails (here: under an address-space limit) ends `lboost train` with one line
// naming the step, never a bare std::bad_alloc; the run folder it created is removed.
TEST_F(CliRefusalsTest, TrainNamesWhatItCouldNotAllocate) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer reserves more address space than the limit";
#endif
  const fs::path run_dir = dir_ / "run";
  const RunResult r =
      test::run_lboost("train --synthetic paper --rounds 2 --out " + run_dir.string(), dir_, "ulimit -v 1500000; ");
  expect_one_error(r, "train", "train: error: out of memory while ");
  EXPECT_NE(r.err.find(" on this machine)"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("bad_alloc"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(run_dir));
}

// A grey PGM image of width x height pixels.
void write_pgm(const fs::path& path, int width, int height) {
  fs::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out << "P5\n" << width << " " << height << "\n255\n";
  for (int i = 0; i < width * height; ++i) out.put(static_cast<char>((i * 37) % 251));
}

TEST_F(CliRefusalsTest, VocabAndMapNameAnImageSmallerThanTheDetectorTakes) {
  write_pgm(dir_ / "images" / "a.pgm", 64, 48);
  write_pgm(dir_ / "images" / "b.pgm", 5, 4);
  expect_one_error(
      test::run_lboost("vocab --images " + (dir_ / "images").string() + " --out " + (dir_ / "vocab.lbv").string(),
                       dir_),
      "vocab",
      (dir_ / "images" / "b.pgm").string() +
          ": image is 5x4 pixels, smaller than the 6x6 that BRISK with 3 octaves takes");
  expect_one_error(test::run_lboost("vocab --detector ORB --images " + (dir_ / "images").string() + " --out " +
                                        (dir_ / "vocab.lbv").string(),
                                    dir_),
                   "vocab", "--images");  // ORB takes 5x4: too few descriptors instead
  EXPECT_FALSE(fs::exists(dir_ / "vocab.lbv"));

  // A collection of one 5x4 image (its camera of the same size).
  const fs::path collection = dir_ / "collection";
  write_pgm(collection / "images" / "map" / "0.pgm", 5, 4);
  fs::create_directories(collection / "sparse");
  std::ofstream(collection / "sparse" / "cameras.txt") << "1 PINHOLE 5 4 4 4 2.5 2\n";
  std::ofstream(collection / "sparse" / "images.txt") << "1 1 0 0 0 0 0 0 1 map/0.pgm\n\n";
  std::ofstream(collection / "sparse" / "points3D.txt") << "";
  expect_one_error(
      test::run_lboost("map --collection " + collection.string() + " --out " + (dir_ / "map.h5").string(), dir_), "map",
      (collection / "images" / "map" / "0.pgm").string() +
          ": image is 5x4 pixels, smaller than the 6x6 that BRISK with 3 octaves takes");
  EXPECT_FALSE(fs::exists(dir_ / "map.h5"));
}

}  // namespace
}  // namespace lmb
