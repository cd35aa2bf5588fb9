// Inputs are never outputs (docs/input_validation.md): every lboost and lboost-bench command that
// writes refuses, before any work, an output that is one of its inputs (any spelling: relative,
// "./x", a hard link, a symbolic link), lies inside an input folder, or is a folder holding an
// input. Each refusal is one line naming both options, exit status 1, and leaves every file of the
// working folder byte for byte as it was. The outputs the jobs and docs write beside their inputs
// still work.
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>

#include <gtest/gtest.h>

#include "common/file_io.h"
#include "test/support/lboost_run.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

using test::RunResult;
using test::slurp;

// Every entry of a folder tree with its bytes (symbolic links as their target).
std::map<std::string, std::string> snapshot(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string name = fs::relative(e.path(), dir).string();
    if (e.is_symlink()) {
      files[name] = "<link to " + fs::read_symlink(e.path()).string() + "> " + slurp(e.path());
    } else {
      files[name] = e.is_regular_file() ? slurp(e.path()) : std::string("<folder>");
    }
  }
  return files;
}

// One working folder for the whole suite: a copy of the tiny world's map, a vocabulary, one run of
// 8 rounds and its model, and small stand-ins for what a refused command never reads (a collection,
// TUM sequences, a bundle of two areas, a gravity file, a split list).
class OutputsNotInputsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const char* map = std::getenv("LMB_TINY_MAP");
    if (map == nullptr || !fs::exists(map)) return;
    root_ = fs::temp_directory_path() / ("lmb_outputs_not_inputs_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    work_ = root_ / "work";
    logs_ = root_ / "logs";
    fs::create_directories(work_);
    fs::create_directories(logs_);
    fs::copy_file(map, work_ / "map.h5");
    const fs::path images = fs::path(map).parent_path() / "collection" / "images";
    ok_ = run("vocab --words 16 --max-descriptors 20000 --seed 7 --images " + images.string() + " --out vocab.lbv")
              .exit_code == 0;
    const RunResult t =
        run("train --map map.h5 --vocab vocab.lbv --rounds 8 --dims-per-round 64 --checkpoint-interval 4 "
            "--calibration-folds 0 --out run");
    ok_ = ok_ && t.exit_code == 0;
    const RunResult e =
        run("export --run run --map map.h5 --vocab vocab.lbv --fusion off --calibration off --out model.lbm");
    ok_ = ok_ && e.exit_code == 0;
    if (!ok_) std::fprintf(stderr, "setup failed: %s%s\n", t.err.c_str(), e.err.c_str());
    fs::create_hard_link(work_ / "map.h5", work_ / "map_link.h5");
    fs::create_symlink("model.lbm", work_ / "model_link.lbm");
    for (const char* name : {"C/sparse/cameras.txt", "C/sparse/images.txt", "C/sparse/points3D.txt", "C/images/a.png",
                             "C/sessions.txt", "C/gravity.txt", "gravity.txt", "list.txt", "tum/rgb.txt",
                             "tum_q/rgb.txt", "areas.txt", "models/areas.txt", "run/other.toml", "run/areas.txt"}) {
      fs::create_directories((work_ / name).parent_path());
      write_file_atomically(work_ / name, std::string(name) + "\n");
    }
    fs::copy_file(work_ / "model.lbm", work_ / "models" / "area-0.lbm");
    fs::copy_file(work_ / "model.lbm", work_ / "models" / "area-1.lbm");
    fs::create_symlink("../map.h5", work_ / "models" / "m.h5");
    write_file_atomically(work_ / "models" / "bundle.txt",
                          "lmb-bundle 1\nreach 5\nareas 2\n"
                          "area 0 file area-0.lbm bytes 10 crc32 0000abcd landmarks 10 cell -9 -9 -9 0 9 9\n"
                          "area 1 file area-1.lbm bytes 10 crc32 0000abcd landmarks 10 cell 0 -9 -9 9 9 9\n");
  }
  static void TearDownTestSuite() {
    if (!root_.empty()) fs::remove_all(root_);
  }
  void SetUp() override {
    if (root_.empty()) GTEST_SKIP() << "LMB_TINY_MAP (a map.h5 of `lboost world --preset tiny`) is not available";
    ASSERT_TRUE(ok_) << "the shared run could not be made";
  }
  // `lboost args` (`lboost-bench args` with bench) run in the working folder: relative paths are
  // relative to it.
  static RunResult run(const std::string& args, bool bench = false) {
    return test::run_program(bench ? LMB_LBOOST_BENCH : LMB_LBOOST, args, logs_, "cd '" + work_.string() + "' && ");
  }
  // `lboost command args` (`lboost-bench command args` with bench) fails with the one line
  // "OUT_OPTION OUT RELATION the input IN_OPTION IN (...)" and changes nothing in the working folder.
  static void expect_refused(const std::string& command, const std::string& args, const std::string& output,
                             const std::string& relation, const std::string& input, bool bench = false) {
    const auto before = snapshot(work_);
    const RunResult r = run(command + " " + args, bench);
    test::expect_one_error(r, command,
                           output + " " + relation + " the input " + input + " (an output never replaces an input)",
                           bench ? "lboost-bench" : "lboost");
    EXPECT_EQ(r.out, "") << command << " " << args;
    EXPECT_TRUE(snapshot(work_) == before) << command << " " << args << ": the working folder changed";
  }
  static fs::path root_, work_, logs_;
  static bool ok_;
};
fs::path OutputsNotInputsTest::root_;
fs::path OutputsNotInputsTest::work_;
fs::path OutputsNotInputsTest::logs_;
bool OutputsNotInputsTest::ok_ = false;

TEST_F(OutputsNotInputsTest, LocalizeAndEvalRefuseTheirInputs) {
  fs::copy_file(work_ / "map.h5", work_ / "m1.h5");
  fs::copy_file(work_ / "map.h5", work_ / "m2.h5");
  const std::string model = "--model model.lbm --map map.h5 ";
  expect_refused("localize", "--model model.lbm --map m1.h5 --out m1.h5", "--out m1.h5", "is", "--map m1.h5");
  expect_refused("localize", model + "--out model.lbm", "--out model.lbm", "is", "--model model.lbm");
  expect_refused("localize", model + "--out ./map.h5", "--out ./map.h5", "is", "--map map.h5");
  expect_refused("localize", model + "--out map_link.h5", "--out map_link.h5", "is", "--map map.h5");
  expect_refused("localize", model + "--out model_link.lbm", "--out model_link.lbm", "is", "--model model.lbm");
  expect_refused("localize", model + "--out " + (work_ / "map.h5").string(), "--out " + (work_ / "map.h5").string(),
                 "is", "--map map.h5");
  const std::string bundle = "--bundle models/bundle.txt --map map.h5 --no-prior ";
  expect_refused("localize", bundle + "--out models/bundle.txt", "--out models/bundle.txt", "is",
                 "--bundle models/bundle.txt");
  expect_refused("localize", bundle + "--out models/area-1.lbm", "--out models/area-1.lbm", "is",
                 "--bundle models/area-1.lbm");
  expect_refused("eval", "--model model.lbm --map m2.h5 --report m2.h5", "--report m2.h5", "is", "--map m2.h5");
  expect_refused("eval", model + "--report r.json --keypoint-ranks model.lbm", "--keypoint-ranks model.lbm", "is",
                 "--model model.lbm");
  expect_refused("eval", model + "--run run --report run/summary.json", "--report run/summary.json", "is",
                 "--run run/summary.json");
  expect_refused("eval", model + "--run run --report run/config.toml", "--report run/config.toml", "is",
                 "--run run/config.toml");
  expect_refused("eval", bundle + "--report models/area-0.lbm", "--report models/area-0.lbm", "is",
                 "--bundle models/area-0.lbm");
}

TEST_F(OutputsNotInputsTest, ExportAndCalibrateRefuseTheirInputs) {
  fs::copy_file(work_ / "vocab.lbv", work_ / "v1.lbv");
  const std::string run = "--run run --map map.h5 --vocab vocab.lbv ";
  expect_refused("export", run + "--out run/model.bin", "--out run/model.bin", "is", "--run run/model.bin");
  expect_refused("export", run + "--out run/config.toml", "--out run/config.toml", "is", "--run run/config.toml");
  expect_refused("export", "--run run --map map.h5 --vocab v1.lbv --out v1.lbv", "--out v1.lbv", "is",
                 "--vocab v1.lbv");
  expect_refused("export", run + "--out map_link.h5", "--out map_link.h5", "is", "--map map.h5");
  expect_refused("export",
                 "--boost-model run/model.bin --map map.h5 --vocab vocab.lbv --fusion off --out run/model.bin",
                 "--out run/model.bin", "is", "--boost-model run/model.bin");
  expect_refused("calibrate", "--model model.lbm --map map.h5 --out model.lbm", "--out model.lbm", "is",
                 "--model model.lbm");
  expect_refused("calibrate", "--model model.lbm --map map.h5 --out map_link.h5", "--out map_link.h5", "is",
                 "--map map.h5");
  expect_refused("calibrate", "--model model.lbm --map map.h5 --run run --out run/config.toml", "--out run/config.toml",
                 "is", "--run run/config.toml");
}

TEST_F(OutputsNotInputsTest, MapAreasBundleVocabAndImportRefuseTheirInputs) {
  expect_refused("map", "--collection C --out C/sparse/images.txt", "--out C/sparse/images.txt", "lies inside",
                 "--collection C/sparse");
  expect_refused("map", "--collection C --out C/sparse", "--out C/sparse", "is", "--collection C/sparse");
  expect_refused("map", "--collection C --out C/images/new.h5", "--out C/images/new.h5", "lies inside",
                 "--collection C/images");
  expect_refused("map", "--collection C --out C/sessions.txt", "--out C/sessions.txt", "is",
                 "--collection C/sessions.txt");
  expect_refused("map", "--collection C --gravity gravity.txt --out gravity.txt", "--out gravity.txt", "is",
                 "--gravity gravity.txt");
  fs::copy_file(work_ / "map.h5", work_ / "m3.h5");
  expect_refused("areas", "--map m3.h5 --out m3.h5", "--out m3.h5", "is", "--map m3.h5");
  expect_refused("areas", "--map map.h5 --out map_link.h5", "--out map_link.h5", "is", "--map map.h5");
  expect_refused("bundle", "--areas areas.txt --models models --out models/area-0.lbm", "--out models/area-0.lbm", "is",
                 "--models models/area-0.lbm");
  expect_refused("bundle", "--areas models/areas.txt --models models --out models/areas.txt", "--out models/areas.txt",
                 "is", "--areas models/areas.txt");
  expect_refused("bundle", "--areas areas.txt --models models --map models/m.h5 --out models/m.h5", "--out models/m.h5",
                 "is", "--map models/m.h5");
  expect_refused("vocab", "--images C/images --out C/images", "--out C/images", "is", "--images C/images");
  expect_refused("vocab", "--images C/images --out C/images/vocab.lbv", "--out C/images/vocab.lbv", "lies inside",
                 "--images C/images");
  expect_refused("vocab", "--images C/images --out C/images/sub/vocab.lbv", "--out C/images/sub/vocab.lbv",
                 "lies inside", "--images C/images");
  const std::string colmap = "--sparse C/sparse --images C/images ";
  expect_refused("import colmap", colmap + "--out C", "--out C", "contains", "--sparse C/sparse");
  expect_refused("import colmap", colmap + "--out C/images/collection", "--out C/images/collection", "lies inside",
                 "--images C/images");
  expect_refused("import colmap", colmap + "--gravity-file gravity.txt --out gravity.txt", "--out gravity.txt", "is",
                 "--gravity-file gravity.txt");
  expect_refused("import colmap", colmap + "--split map-list:list.txt --out list.txt", "--out list.txt", "is",
                 "--split list.txt");
  expect_refused("import tum", "--data tum --out tum", "--out tum", "is", "--data tum");
  expect_refused("import tum", "--data C/images --out C", "--out C", "contains", "--data C/images");
  expect_refused("import tum", "--data tum --query-data tum_q --out tum_q/collection", "--out tum_q/collection",
                 "lies inside", "--query-data tum_q");
}

TEST_F(OutputsNotInputsTest, TrainRefusesARunFolderHoldingItsInputs) {
  const auto refused = [&](const std::string& args, const std::string& output, const std::string& relation,
                           const std::string& input) {
    expect_refused("train", "--map map.h5 --vocab vocab.lbv --rounds 8 " + args, output, relation, input);
  };
  refused("--out map.h5", "--out map.h5", "is", "--map map.h5");
  refused("--out .", "--out .", "contains", "--map map.h5");
  refused("--out " + work_.string(), "--out " + work_.string(), "contains", "--map map.h5");
  refused("--config run/other.toml --out run", "--out run", "contains", "--config run/other.toml");
  refused("--area run/areas.txt:0 --out run", "--out run", "contains", "--area run/areas.txt");
}

TEST_F(OutputsNotInputsTest, BenchRefusesItsInputsAsJson) {
  const auto refused = [&](const std::string& command, const std::string& args, const std::string& output,
                           const std::string& input) {
    expect_refused(command, args, output, "is", input, /*bench=*/true);
  };
  refused("context", "--map map.h5 --vocab vocab.lbv --json vocab.lbv", "--json vocab.lbv", "--vocab vocab.lbv");
  refused("context", "--map map.h5 --vocab vocab.lbv --json map.h5", "--json map.h5", "--map map.h5");
  refused("infer", "--model model.lbm --map map.h5 --json model.lbm", "--json model.lbm", "--model model.lbm");
  refused("pose", "--model model.lbm --map map.h5 --json map_link.h5", "--json map_link.h5", "--map map.h5");
  const std::string bundle = "--bundle models/bundle.txt --map map.h5 --model model.lbm ";
  refused("bundle", bundle + "--json models/bundle.txt", "--json models/bundle.txt", "--bundle models/bundle.txt");
  refused("bundle", bundle + "--json models/area-1.lbm", "--json models/area-1.lbm", "--bundle models/area-1.lbm");
  refused("bundle", bundle + "--json model_link.lbm", "--json model_link.lbm", "--model model.lbm");
}

// What the jobs and docs write beside their inputs: export into the run folder, a resume given the
// run's own config.toml, a map written into its collection folder.
TEST_F(OutputsNotInputsTest, OutputsBesideTheInputsStillWork) {
  auto before = snapshot(work_ / "run");
  const RunResult e =
      run("export --run run --map map.h5 --vocab vocab.lbv --fusion off --calibration off --out run/model.lbm");
  ASSERT_EQ(e.exit_code, 0) << e.err;
  EXPECT_EQ(slurp(work_ / "run" / "model.lbm"), slurp(work_ / "model.lbm"));
  before["model.lbm"] = slurp(work_ / "model.lbm");
  EXPECT_TRUE(snapshot(work_ / "run") == before);
  fs::copy(work_ / "run", work_ / "run2", fs::copy_options::recursive);
  const RunResult t = run("train --map map.h5 --vocab vocab.lbv --config run2/config.toml --out run2");
  ASSERT_EQ(t.exit_code, 0) << t.err;
  EXPECT_EQ(slurp(work_ / "run2" / "model.bin"), slurp(work_ / "run" / "model.bin"));
  // Past the check, map stops at its next one.
  test::expect_one_error(run("map --collection C --label a,b --out C/map.h5"), "map", "--label: 2 labels for 1");
}

}  // namespace
}  // namespace lmb
