// lboost-bench, the benchmarks' own tool, and lboost without them: the subcommands each one lists in
// its help; the bundle modes' options, the same in lboost and lboost-bench; lboost-bench's errors, one line naming the
// benchmark; small runs of `boost`, of `dist` on 2 MPI ranks, and of `pose` on the tiny world (its settings and JSON).
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "test/support/lboost_run.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

using test::expect_one_error;
using test::RunResult;
using test::slurp;

class BenchCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lmb_bench_cli_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

// The subcommand names of a CLI11 help text: the first word of each indented line after
// "Subcommands:".
std::set<std::string> subcommands(const std::string& help) {
  std::set<std::string> names;
  const size_t at = help.find("Subcommands:");
  if (at == std::string::npos) return names;
  std::istringstream lines(help.substr(at));
  std::string line;
  std::getline(lines, line);
  while (std::getline(lines, line)) {
    if (line.rfind("  ", 0) != 0) break;
    std::istringstream words(line);
    std::string name;
    words >> name;
    names.insert(name);
  }
  return names;
}

TEST_F(BenchCliTest, LboostListsNoBenchmarkAndLboostBenchListsThemAll) {
  const RunResult lboost = test::run_lboost("--help", dir_);
  ASSERT_EQ(lboost.exit_code, 0) << lboost.err;
  const std::set<std::string> commands = subcommands(lboost.out);
  EXPECT_TRUE(commands.count("train")) << lboost.out;
  EXPECT_FALSE(commands.count("bench")) << lboost.out;
  EXPECT_EQ(lboost.out.find("bench"), std::string::npos) << lboost.out;
  const RunResult old_command = test::run_lboost("bench context --synthetic 1", dir_);
  EXPECT_EQ(old_command.exit_code, 1) << old_command.err;
  EXPECT_EQ(old_command.err.rfind("lboost: error: ", 0), 0u) << old_command.err;

  const RunResult bench = test::run_lboost_bench("--help", dir_);
  ASSERT_EQ(bench.exit_code, 0) << bench.err;
  EXPECT_EQ(subcommands(bench.out), (std::set<std::string>{"context", "infer", "pose", "bundle", "boost", "dist"}))
      << bench.out;
  for (const std::string command : {"context", "infer", "pose", "bundle", "boost", "dist"}) {
    const RunResult help = test::run_lboost_bench(command + " --help", dir_);
    EXPECT_EQ(help.exit_code, 0) << command << ": " << help.err;
    EXPECT_NE(help.out.find("--json"), std::string::npos) << command << ": " << help.out;
  }
}

// The lines of a help text's "With --bundle:" group, each option with its help (a help that CLI11
// wraps onto the next line joined to its option), defaults removed ("FLOAT=5 ..." -> "FLOAT ...").
std::map<std::string, std::string> bundle_group(const std::string& help) {
  std::map<std::string, std::string> options;
  const size_t at = help.find("With --bundle:");
  if (at == std::string::npos) return options;
  std::istringstream lines(help.substr(at));
  std::string line, name;
  std::getline(lines, line);
  while (std::getline(lines, line) && !line.empty()) {
    std::istringstream words(line);
    std::string first;
    words >> first;
    if (first.rfind("--", 0) == 0) name = first;
    std::string rest((std::istreambuf_iterator<char>(words)), std::istreambuf_iterator<char>());
    options[name] += rest;
  }
  for (auto& [option, text] : options) {
    text = std::regex_replace(text, std::regex("=[^ ]+"), "");
    text = std::regex_replace(text, std::regex(" +"), " ");
  }
  return options;
}

// One definition per concept: the options of the bundle's modes read the same (name, type, help)
// in lboost localize, lboost eval and lboost-bench bundle, defaults aside; --prior-noise and
// --track are lists in all three.
TEST_F(BenchCliTest, BundleModeOptionsAreTheSameInEveryCommand) {
  const auto help = [&](bool bench, const std::string& command) {
    const RunResult r =
        bench ? test::run_lboost_bench(command + " --help", dir_) : test::run_lboost(command + " --help", dir_);
    EXPECT_EQ(r.exit_code, 0) << command << ": " << r.err;
    return bundle_group(r.out);
  };
  const auto localize = help(false, "localize"), eval = help(false, "eval"), bench = help(true, "bundle");
  ASSERT_GE(localize.size(), 10u);
  EXPECT_EQ(localize, eval);
  EXPECT_EQ(localize, bench);
  for (const std::string list : {"--prior-noise", "--track"}) {
    ASSERT_TRUE(bench.count(list));
    EXPECT_NE(bench.at(list).find("FLOAT ..."), std::string::npos) << list << ": " << bench.at(list);
  }
}

TEST_F(BenchCliTest, ErrorsAreOneLineNamingTheBenchmark) {
  const RunResult none = test::run_lboost_bench("", dir_);
  EXPECT_EQ(none.exit_code, 1) << none.err;
  EXPECT_EQ(none.err.rfind("lboost-bench: error: ", 0), 0u) << none.err;
  expect_one_error(test::run_lboost_bench("pose --model " + (dir_ / "none.lbm").string() + " --map m.h5", dir_), "pose",
                   "--model", "lboost-bench");
  const fs::path model = dir_ / "model.lbm", map = dir_ / "map.h5";
  std::ofstream(model) << "not a model\n";
  std::ofstream(map) << "not a map\n";
  const std::string pose = "pose --model " + model.string() + " --map " + map.string();
  expect_one_error(test::run_lboost_bench(pose + " --seeds 0", dir_), "pose", "--seeds 0 must be in 1..1000",
                   "lboost-bench");
  expect_one_error(test::run_lboost_bench(pose + " --budgets 50,0", dir_), "pose", "--budgets: 0 must be >= 1",
                   "lboost-bench");
  expect_one_error(test::run_lboost_bench(pose + " --plain-iterations 0", dir_), "pose",
                   "--plain-iterations 0 must be >= 1", "lboost-bench");
  expect_one_error(test::run_lboost_bench("context", dir_), "context", "give --map map.h5 or --synthetic N",
                   "lboost-bench");
  expect_one_error(test::run_lboost_bench("boost --rounds x", dir_), "boost", "--rounds", "lboost-bench");
}

// A learner problem small enough for a test: 8 classes, 128 + 64 dims.
const std::string kSmallShape =
    " --classes 8 --observations 6 --background 40 --context-dims 128 --descriptor-bits 64 --rounds 2 "
    "--dims-per-round 32";

TEST_F(BenchCliTest, BoostAndDistRunASmallProblem) {
  const fs::path boost_json = dir_ / "boost.json";
  const RunResult boost = test::run_lboost_bench("boost" + kSmallShape + " --json " + boost_json.string(), dir_);
  ASSERT_EQ(boost.exit_code, 0) << boost.err;
  EXPECT_NE(boost.err.find("lboost-bench boost: machine "), std::string::npos) << boost.err;
  const nlohmann::json b = nlohmann::json::parse(slurp(boost_json));
  EXPECT_EQ(b["num_classes"], 8);
  EXPECT_EQ(b["num_dims"], 128 + 64);
  EXPECT_GT(b["seconds_per_round"].get<double>(), 0.0);
  EXPECT_EQ(nlohmann::json::parse(boost.out), b);

  const fs::path dist_json = dir_ / "dist.json";
  const RunResult dist = test::run_lboost_bench("dist" + kSmallShape + " --json " + dist_json.string(), dir_,
                                                std::string(LMB_MPIEXEC) + " -n 2 ");
  ASSERT_EQ(dist.exit_code, 0) << dist.err;
  const nlohmann::json d = nlohmann::json::parse(slurp(dist_json));
  EXPECT_EQ(d["ranks"], 2);
  EXPECT_EQ(d["num_classes"], 8);
  EXPECT_EQ(d["rounds"], 2);
  EXPECT_GT(d["bytes_sent_per_round_all_ranks"].get<double>(), 0.0);
}

// `pose` on a model of the tiny world: every setting of the estimator in table order, each with its
// sampling, local optimisation and budget (a budget once); plain RANSAC never refines.
TEST_F(BenchCliTest, PoseComparesTheEstimatorsSettings) {
  const char* map = std::getenv("LMB_TINY_MAP");
  if (map == nullptr || !fs::exists(map)) GTEST_SKIP() << "LMB_TINY_MAP (a map.h5 of `lboost world --preset tiny`)";
  const std::string images = (fs::path(map).parent_path() / "collection" / "images").string();
  const std::string vocab = (dir_ / "vocab.lbv").string(), run = (dir_ / "run").string(),
                    model = (dir_ / "model.lbm").string(), json = (dir_ / "pose.json").string();
  for (const std::string& step :
       {"vocab --words 16 --max-descriptors 20000 --seed 7 --images " + images + " --out " + vocab,
        "train --map " + std::string(map) + " --vocab " + vocab + " --rounds 8 --dims-per-round 64 --out " + run,
        "export --run " + run + " --map " + std::string(map) + " --vocab " + vocab +
            " --fusion off --calibration off --out " + model}) {
    const RunResult r = test::run_lboost(step, dir_);
    ASSERT_EQ(r.exit_code, 0) << step << ": " << r.err;
  }
  const RunResult r =
      test::run_lboost_bench("pose --model " + model + " --map " + map +
                                 " --seeds 2 --iterations 20 --budgets 10,40,20,10 --plain-iterations 30 "
                                 "--max-frames 4 --json " +
                                 json,
                             dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("plain_ransac"), std::string::npos) << r.out;
  const nlohmann::json j = nlohmann::json::parse(slurp(json));
  EXPECT_GT(j["frames"].get<int>(), 0);
  EXPECT_LE(j["frames"].get<int>(), 4);
  EXPECT_EQ(j["seeds"], 2);
  EXPECT_EQ(j["settings"]["budgets"], (std::vector<int>{10, 40, 20, 10}));
  const nlohmann::json& s = j["solvers"];
  ASSERT_EQ(s.size(), 5u) << s.dump(1);
  const std::vector<std::string> names = {"plain_ransac", "lo_ransac_prosac", "lo_ransac_prosac", "lo_ransac_prosac",
                                          "lo_ransac_uniform"};
  const std::vector<int> iterations = {30, 20, 10, 40, 20};
  const std::vector<std::string> sampling = {"uniform", "prosac", "prosac", "prosac", "uniform"};
  for (size_t k = 0; k < s.size(); ++k) {
    SCOPED_TRACE(k);
    EXPECT_EQ(s[k]["name"], names[k]);
    EXPECT_EQ(s[k]["iterations"], iterations[k]);
    EXPECT_EQ(s[k]["sampling"], sampling[k]);
    EXPECT_EQ(s[k]["local_optimization"], k > 0);
    EXPECT_EQ(s[k]["recall_per_seed"].size(), 2u);
    EXPECT_LE(s[k]["samples_per_frame"].get<double>(), iterations[k]);
    EXPECT_GT(s[k]["cpu_ms_per_frame"].get<double>(), 0.0);
    for (size_t seed = 0; seed < 2; ++seed) {
      EXPECT_LE(s[k]["correct_per_seed"][seed].get<int>(), s[k]["localized_per_seed"][seed].get<int>());
    }
  }
  EXPECT_EQ(s[0]["refinements_per_frame"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(s[0]["speedup_vs_plain_ransac"].get<double>(), 1.0);
}

}  // namespace
}  // namespace lmb
