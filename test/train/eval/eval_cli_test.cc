// `lboost eval` end to end on the tiny rendered world (the lmb_tiny_world fixture of
// test/train/export): vocab -> train (few rounds) -> export -> eval, then the report's schema, its
// dataset counts against the map, metric ranges, and bruteforce_hamming's precision@1 against a
// brute-force nearest neighbour computed here; and one-line errors for mismatched inputs.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/hamming.h"
#include "common/io/map_h5.h"
#include "infer/model.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

struct RunResult {
  int exit_code = 0;
  std::string out, err;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

RunResult run(const std::string& args, const fs::path& dir) {
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string command = std::string(LMB_LBOOST) + " " + args + " > " + out.string() + " 2> " + err.string();
  const int status = std::system(command.c_str());
  return RunResult{WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(out), slurp(err)};
}

void expect_one_error_line(const RunResult& r, const std::string& needle) {
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.err.rfind("lboost eval: error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
}

class EvalCliTest : public ::testing::Test {
 protected:
  // One trained model for all tests of the suite.
  static void SetUpTestSuite() {
    const char* map = std::getenv("LMB_TINY_MAP");
    if (map == nullptr || !fs::exists(map)) return;
    map_ = map;
    dir_ = fs::temp_directory_path() / ("lmb_eval_cli_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const fs::path images = map_.parent_path() / "collection" / "images";
    const std::string m = " --map " + map_.string();
    ok_ = run("vocab --images " + images.string() + " --out " + (dir_ / "vocab.lbv").string() + " --words 16 --seed 7",
              dir_).exit_code == 0 &&
          run("train" + m + " --vocab " + (dir_ / "vocab.lbv").string() + " --out " + (dir_ / "run").string() +
                  " --rounds 20 --dims-per-round 100 --threads 2",
              dir_).exit_code == 0 &&
          run("export --run " + (dir_ / "run").string() + m + " --vocab " + (dir_ / "vocab.lbv").string() +
                  " --out " + (dir_ / "model.lbm").string(),
              dir_).exit_code == 0;
    if (!ok_) return;
    eval_ = run("eval --model " + (dir_ / "model.lbm").string() + m + " --run " + (dir_ / "run").string() +
                    " --report " + (dir_ / "report.json").string() + " --keypoint-ranks " +
                    (dir_ / "ranks.json").string(),
                dir_);
  }
  static void TearDownTestSuite() {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  void SetUp() override {
    if (map_.empty()) GTEST_SKIP() << "LMB_TINY_MAP (a map.h5 of `lboost world --preset tiny`) is not available";
    ASSERT_TRUE(ok_) << "vocab / train / export failed: " << slurp(dir_ / "stderr.txt");
  }

  static fs::path map_, dir_;
  static bool ok_;
  static RunResult eval_;
};
fs::path EvalCliTest::map_, EvalCliTest::dir_;
bool EvalCliTest::ok_ = false;
RunResult EvalCliTest::eval_;

TEST_F(EvalCliTest, ReportSchemaCountsAndRanges) {
  ASSERT_EQ(eval_.exit_code, 0) << eval_.err;
  // The results table is printed, one row per method.
  for (const char* name : {"landmarkboost ", "landmarkboost_invfile", "bruteforce_hamming", "hamming_ratio ",
                           "hamming_ratio_2nn", "faiss_hnsw_ratio", "projected_kdtree"}) {
    EXPECT_NE(eval_.out.find(name), std::string::npos) << name << "\n" << eval_.out;
  }
  const nlohmann::json report = nlohmann::json::parse(slurp(dir_ / "report.json"));
  const LandmarkMap map = read_map_h5(map_);
  int64_t map_frames = 0, query_frames = 0, query_keypoints = 0, with_truth = 0;
  for (const MapFrame& f : map.frames) {
    (f.is_query ? query_frames : map_frames) += 1;
    if (!f.is_query) continue;
    query_keypoints += f.num_keypoints;
    for (int32_t k = 0; k < f.num_keypoints; ++k) with_truth += map.keypoint_landmark[f.first_keypoint + k] >= 0;
  }
  const nlohmann::json& d = report.at("dataset");
  EXPECT_EQ(d.at("map_frames").get<int64_t>(), map_frames);
  EXPECT_EQ(d.at("query_frames").get<int64_t>(), query_frames);
  EXPECT_EQ(d.at("landmarks").get<int64_t>(), static_cast<int64_t>(map.landmarks.size()));
  EXPECT_EQ(d.at("query_keypoints").get<int64_t>(), query_keypoints);
  EXPECT_EQ(d.at("query_keypoints_with_truth").get<int64_t>(), with_truth);
  EXPECT_GT(query_frames, 0);

  const nlohmann::json& methods = report.at("methods");
  ASSERT_EQ(methods.size(), 7u);
  for (const auto& [name, m] : methods.items()) {
    SCOPED_TRACE(name);
    for (const char* key : {"precision_at_1", "mrr", "pose_recall_20cm_5deg", "pose_auc", "mean_inlier_ratio"}) {
      const double v = m.at(key).get<double>();
      EXPECT_GE(v, 0.0) << key;
      EXPECT_LE(v, 1.0) << key;
    }
    EXPECT_GE(m.at("mrr").get<double>(), m.at("precision_at_1").get<double>());
    EXPECT_LE(m.at("pose_auc").get<double>(), m.at("pose_recall_20cm_5deg").get<double>() + 1e-12);
    for (const char* fppi : {"0.1", "1", "10"}) {
      const double v = m.at("miss_rate_at_fppi").at(fppi).get<double>();
      EXPECT_GE(v, 0.0);
      EXPECT_LE(v, 1.0);
    }
    // Miss rate is non-increasing in FPPI and 1 - miss rate at depth 1 is precision@1.
    EXPECT_GE(m.at("miss_rate_at_fppi").at("0.1").get<double>(), m.at("miss_rate_at_fppi").at("10").get<double>());
    EXPECT_NEAR(m.at("miss_rate_curve").at("miss_rate")[1].get<double>(), 1.0 - m.at("precision_at_1").get<double>(),
                1e-12);
    EXPECT_GT(m.at("match_ms_per_frame").get<double>(), 0.0);
    EXPECT_GE(m.at("total_ms_per_frame").get<double>(), m.at("match_ms_per_frame").get<double>());
    EXPECT_EQ(m.at("per_frame").at("match_ms").size(), static_cast<size_t>(query_frames));
    // At least the medians are numbers when something localized.
    if (m.at("frames_localized").get<int>() > 0) {
      EXPECT_TRUE(m.at("median_position_error_m").is_number());
    }
    // The sweep: 3 budgets x 5 seeds; its 500-iteration run with seed 0 is the reported pose run
    // (--ransac-iterations 500, --seed 0), and mean/min/max summarize the seeds.
    const nlohmann::json& sweep = m.at("pose_recall_sweep");
    EXPECT_EQ(sweep.at("ransac_iterations"), nlohmann::json({50, 100, 500}));
    EXPECT_EQ(sweep.at("seeds"), nlohmann::json({0, 1, 2, 3, 4}));
    EXPECT_DOUBLE_EQ(sweep.at("recall")[2][0].get<double>(),
                     m.at("frames_correct").get<double>() / static_cast<double>(query_frames));
    for (size_t b = 0; b < 3; ++b) {
      const auto row = sweep.at("recall")[b].get<std::vector<double>>();
      double mean = 0;
      for (double r : row) mean += r / 5.0;
      EXPECT_NEAR(sweep.at("mean")[b].get<double>(), mean, 1e-12);
      EXPECT_EQ(sweep.at("min")[b].get<double>(), *std::min_element(row.begin(), row.end()));
      EXPECT_EQ(sweep.at("max")[b].get<double>(), *std::max_element(row.begin(), row.end()));
    }
  }
  EXPECT_EQ(report.at("settings").at("method_parameters").at("hamming_ratio").at("ratio").get<double>(), 0.8);
  EXPECT_EQ(report.at("settings").at("method_parameters").at("faiss_hnsw_ratio").at("hnsw_m").get<int>(), 32);
  // The descriptor baseline localizes the tiny world's query frames (it has little aliasing).
  EXPECT_GT(methods.at("bruteforce_hamming").at("pose_recall_20cm_5deg").get<double>(), 0.5);
  // The training summary is carried over, and the side file ranks every query keypoint.
  EXPECT_TRUE(report.at("training").contains("validation_p1"));
  const nlohmann::json ranks = nlohmann::json::parse(slurp(dir_ / "ranks.json"));
  EXPECT_EQ(ranks.at("truth_rank").at("landmarkboost").size(), static_cast<size_t>(query_frames));
}

// bruteforce_hamming's precision@1 equals exact Hamming nearest neighbour computed here: the
// training observations are the non-query keypoints of the model's landmarks; a query keypoint
// counts when its true landmark is a model class; ties go to the first observation in map order.
TEST_F(EvalCliTest, BruteforceHammingMatchesAnIndependentNearestNeighbour) {
  ASSERT_EQ(eval_.exit_code, 0) << eval_.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(dir_ / "report.json"));
  const LandmarkMap map = read_map_h5(map_);
  const std::shared_ptr<const Model> model = Model::load(dir_ / "model.lbm");
  std::vector<char> is_class(map.landmarks.size(), 0);
  for (int32_t c = 0; c < model->num_classes(); ++c) is_class[model->class_landmark(c)] = 1;
  std::vector<int64_t> train;
  for (const MapFrame& f : map.frames) {
    if (f.is_query) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[k];
      if (l >= 0 && is_class[l]) train.push_back(k);
    }
  }
  ASSERT_FALSE(train.empty());
  int64_t total = 0, correct = 0;
  for (const MapFrame& f : map.frames) {
    if (!f.is_query) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      const landmark_t truth = map.keypoint_landmark[k];
      if (truth < 0 || !is_class[truth]) continue;
      int best = 1 << 30;
      landmark_t best_landmark = -1;
      for (int64_t t : train) {
        const int d = hamming_distance(map.descriptor(k), map.descriptor(t), map.descriptor_bytes);
        if (d < best) {
          best = d;
          best_landmark = map.keypoint_landmark[t];
        }
      }
      ++total;
      correct += best_landmark == truth;
    }
  }
  ASSERT_GT(total, 0);
  EXPECT_EQ(report.at("dataset").at("query_keypoints_with_class_truth").get<int64_t>(), total);
  EXPECT_DOUBLE_EQ(report.at("methods").at("bruteforce_hamming").at("precision_at_1").get<double>(),
                   static_cast<double>(correct) / static_cast<double>(total));
}

TEST_F(EvalCliTest, MismatchedInputsGiveOneLineErrors) {
  LandmarkMap map = read_map_h5(map_);
  const std::string model = " --model " + (dir_ / "model.lbm").string();
  const std::string report = " --report " + (dir_ / "bad_report.json").string();
  // A map whose landmarks moved: the model was trained on another map.
  LandmarkMap moved = map;
  for (Landmark& l : moved.landmarks) l.position.x() += 1.0;
  write_map_h5(moved, dir_ / "moved.h5");
  expect_one_error_line(run("eval" + model + " --map " + (dir_ / "moved.h5").string() + report, dir_),
                        "trained on another map");
  // A map without query frames.
  LandmarkMap no_query = map;
  for (MapFrame& f : no_query.frames) f.is_query = false;
  for (Landmark& l : no_query.landmarks) {
    l.num_map_observations += l.num_query_observations;
    l.num_query_observations = 0;
  }
  write_map_h5(no_query, dir_ / "no_query.h5");
  expect_one_error_line(run("eval" + model + " --map " + (dir_ / "no_query.h5").string() + report, dir_),
                        "no query frames");
  // An unknown method.
  expect_one_error_line(run("eval" + model + " --map " + map_.string() + report + " --methods landmarkboost,faiss",
                            dir_),
                        "unknown method 'faiss'");
  EXPECT_FALSE(fs::exists(dir_ / "bad_report.json"));
}

}  // namespace
}  // namespace lmb
