// `lboost eval` end to end on the tiny rendered world (the lmb_tiny_world fixture of
// test/train/export): vocab -> train (few rounds) -> export -> eval, then the report's schema
// (against docs/report.md), its dataset counts against the map, metric ranges, bruteforce_hamming's
// precision@1 and hamming_ratio's accepted matches against references computed here, the metric
// names shared with `lboost localize`, non-finite options and pose thresholds; and one-line
// errors for mismatched inputs.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/hamming.h"
#include "common/io/map_h5.h"
#include "infer/model.h"
#include "test/support/lboost_run.h"
#include "train/boost/train_config.h"
#include "train/boost/training_set.h"
#include "train/eval/landmarkboost_matcher.h"
#include "train/export/descriptor_fusion.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

using test::RunResult;
using test::slurp;

RunResult run(const std::string& args, const fs::path& dir, const std::string& prefix = "") {
  return test::run_lboost(args, dir, prefix);
}

// The field paths of a report: objects' keys joined by '.', method names as <method>, session
// names as <session>, arrays of objects as [], the copied training summary as one field.
void report_paths(const nlohmann::json& j, const std::string& path, std::set<std::string>& out) {
  static const std::set<std::string> by_method = {"methods",
                                                  "settings.index_build_seconds",
                                                  "settings.method_parameters",
                                                  "sessions[].methods",
                                                  "held_out_map_observations.methods",
                                                  "generalization_gap.precision_at_1",
                                                  "generalization_gap.pose_recall_20cm_5deg"};
  static const std::set<std::string> by_session = {"generalization_gap.precision_at_1.<method>.sessions",
                                                   "generalization_gap.pose_recall_20cm_5deg.<method>"};
  if (j.is_object() && path != "training") {
    for (const auto& [key, value] : j.items()) {
      const std::string k = by_method.count(path) ? "<method>" : by_session.count(path) ? "<session>" : key;
      report_paths(value, path.empty() ? k : path + "." + k, out);
    }
  } else if (j.is_array() && !j.empty() && j.front().is_object()) {
    for (const auto& value : j) report_paths(value, path + "[]", out);
  } else {
    out.insert(path);
  }
}

void expect_eval_error(const RunResult& r, const std::string& needle) { test::expect_one_error(r, "eval", needle); }

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
    const auto step = [](const std::string& args) {
      const RunResult r = run(args, dir_);
      if (r.exit_code != 0) setup_error_ = args.substr(0, args.find(' ')) + ": " + r.err;
      return r.exit_code == 0;
    };
    ok_ = step("vocab --images " + images.string() + " --out " + (dir_ / "vocab.lbv").string() +
               " --words 16 --seed 7") &&
          step("train" + m + " --vocab " + (dir_ / "vocab.lbv").string() + " --out " + (dir_ / "run").string() +
               " --rounds 20 --dims-per-round 100 --threads 2") &&
          step("export --run " + (dir_ / "run").string() + m + " --vocab " + (dir_ / "vocab.lbv").string() + " --out " +
               (dir_ / "model.lbm").string());
    if (!ok_) return;
    eval_ = run("eval --model " + (dir_ / "model.lbm").string() + m + " --run " + (dir_ / "run").string() +
                    " --vocab " + (dir_ / "vocab.lbv").string() + " --report " + (dir_ / "report.json").string() +
                    " --keypoint-ranks " + (dir_ / "ranks.json").string(),
                dir_);
  }
  static void TearDownTestSuite() {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  void SetUp() override {
    if (map_.empty()) GTEST_SKIP() << "LMB_TINY_MAP (a map.h5 of `lboost world --preset tiny`) is not available";
    ASSERT_TRUE(ok_) << "vocab / train / export failed: " << setup_error_;
  }

  static fs::path map_, dir_;
  static bool ok_;
  static std::string setup_error_;
  static RunResult eval_;
};
fs::path EvalCliTest::map_, EvalCliTest::dir_;
bool EvalCliTest::ok_ = false;
std::string EvalCliTest::setup_error_;
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
    for (const char* key : {"precision_at_1", "mrr", "pose_recall_20cm_5deg", "pose_auc", "mean_inlier_ratio",
                            "match_precision", "match_recall", "background_rejection_rate"}) {
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
    EXPECT_EQ(m.at("pose_recall_at_thresholds").size(), 1u);
    EXPECT_EQ(m.at("pose_recall_at_thresholds")[0].at("recall"), m.at("pose_recall_20cm_5deg"));
  }
  // Background rejection is measured on what localization rejects: LandmarkBoost rejects at
  // margin 0 (the default), the ratio test rejects, plain nearest neighbours never do.
  EXPECT_GT(methods.at("landmarkboost").at("background_rejection_rate").get<double>(), 0.0);
  EXPECT_GT(methods.at("hamming_ratio").at("background_rejection_rate").get<double>(), 0.0);
  EXPECT_EQ(methods.at("bruteforce_hamming").at("background_rejection_rate").get<double>(), 0.0);
  EXPECT_EQ(methods.at("bruteforce_hamming").at("match_recall"), methods.at("bruteforce_hamming").at("precision_at_1"));
  EXPECT_EQ(report.at("settings").at("method_parameters").at("hamming_ratio").at("ratio").get<double>(), 0.8);
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

// hamming_ratio's accepted matches against Lowe's ratio test computed here over the same
// observations: the nearest observation (d1) against the nearest of another landmark (d2),
// accepted when d1 < 0.8 d2; match precision, recall and background rejection follow.
TEST_F(EvalCliTest, HammingRatioMatchesAnIndependentRatioTest) {
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
  int64_t with_truth = 0, background = 0, accepted = 0, correct = 0, background_rejected = 0;
  for (const MapFrame& f : map.frames) {
    if (!f.is_query) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      int d1 = 1 << 30;
      landmark_t l1 = -1;
      for (int64_t t : train) {
        const int d = hamming_distance(map.descriptor(k), map.descriptor(t), map.descriptor_bytes);
        if (d < d1) {
          d1 = d;
          l1 = map.keypoint_landmark[t];
        }
      }
      int d2 = 1 << 30;
      for (int64_t t : train) {
        if (map.keypoint_landmark[t] == l1) continue;
        d2 = std::min(d2, hamming_distance(map.descriptor(k), map.descriptor(t), map.descriptor_bytes));
      }
      const bool accept = d1 < 0.8 * d2;
      const landmark_t l = map.keypoint_landmark[k];
      const landmark_t truth = l >= 0 && is_class[l] ? l : -1;
      (truth >= 0 ? with_truth : background) += 1;
      accepted += accept;
      correct += accept && l1 == truth;
      background_rejected += truth < 0 && !accept;
    }
  }
  ASSERT_GT(accepted, 0);
  const nlohmann::json& m = report.at("methods").at("hamming_ratio");
  EXPECT_DOUBLE_EQ(m.at("match_precision").get<double>(), static_cast<double>(correct) / accepted);
  EXPECT_DOUBLE_EQ(m.at("match_recall").get<double>(), static_cast<double>(correct) / with_truth);
  EXPECT_DOUBLE_EQ(m.at("background_rejection_rate").get<double>(),
                   static_cast<double>(background_rejected) / background);
}

// --min-margin -inf: no rejection (LandmarkBoost then accepts every keypoint's top landmark, so its
// match recall is its precision@1), written to the report as the string "-inf"; pose recall at
// every --pose-thresholds pair, from the per-frame errors.
TEST_F(EvalCliTest, MinMarginInfAndPoseThresholds) {
  const RunResult r = run("eval --model " + (dir_ / "model.lbm").string() + " --map " + map_.string() + " --report " +
                              (dir_ / "report_inf.json").string() +
                              " --methods landmarkboost,bruteforce_hamming --min-margin -inf"
                              " --pose-thresholds '0.2,5;1,2;0.05,1' --ransac-sweep-iterations 20,40"
                              " --ransac-sweep-seeds 2",
                          dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(dir_ / "report_inf.json"));
  EXPECT_EQ(report.at("settings").at("landmarkboost_min_margin"), "-inf");
  EXPECT_EQ(report.at("settings").at("method_parameters").at("landmarkboost").at("min_margin"), "-inf");
  const nlohmann::json& lb = report.at("methods").at("landmarkboost");
  EXPECT_EQ(lb.at("background_rejection_rate").get<double>(), 0.0);
  EXPECT_EQ(lb.at("match_recall"), lb.at("precision_at_1"));
  EXPECT_EQ(lb.at("pose_recall_sweep").at("ransac_iterations"), nlohmann::json({20, 40}));
  const double limits[3][2] = {{0.2, 5}, {1, 2}, {0.05, 1}};
  for (const auto& [name, m] : report.at("methods").items()) {
    SCOPED_TRACE(name);
    const nlohmann::json& at = m.at("pose_recall_at_thresholds");
    ASSERT_EQ(at.size(), 3u);
    const nlohmann::json& pf = m.at("per_frame");
    for (size_t t = 0; t < 3; ++t) {
      EXPECT_EQ(at[t].at("max_position_error_m").get<double>(), limits[t][0]);
      EXPECT_EQ(at[t].at("max_rotation_error_deg").get<double>(), limits[t][1]);
      int64_t correct = 0;
      for (size_t f = 0; f < pf.at("position_error_m").size(); ++f) {
        if (pf.at("position_error_m")[f].is_null()) continue;
        correct += pf.at("position_error_m")[f].get<double>() <= limits[t][0] * (1 + 1e-9) &&
                   pf.at("rotation_error_deg")[f].get<double>() <= limits[t][1] * (1 + 1e-9);
      }
      EXPECT_EQ(at[t].at("frames_correct").get<int64_t>(), correct);
    }
    EXPECT_EQ(m.at("frames_correct"), at[0].at("frames_correct"));  // the first pair is the primary
  }
  // The printed table has a column a pair; the default run's table has none.
  EXPECT_NE(r.out.find("pose recall at each --pose-thresholds pair"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("0.05 m, 1 deg"), std::string::npos) << r.out;
  EXPECT_EQ(eval_.out.find("pose recall at each --pose-thresholds pair"), std::string::npos) << eval_.out;
  expect_eval_error(run("eval --model " + (dir_ / "model.lbm").string() + " --map " + map_.string() + " --report " +
                            (dir_ / "bad_report.json").string() + " --pose-thresholds 0.2",
                        dir_),
                    "--pose-thresholds '0.2': '0.2' is not METRES,DEGREES");
}

// --inverted-file-words: the inverted file's candidates from a keypoint's N nearest words. An
// exported model lists every class under the words of its training observations, so with every
// word the inverted file ranks exactly as the dense classifier (the same P@1, MRR, keypoint ranks
// and accepted matches); the setting is recorded with the method; out of range is a one-line error.
TEST_F(EvalCliTest, InvertedFileWithEveryWordRanksAsDense) {
  const Vocabulary vocabulary = Vocabulary::load(dir_ / "vocab.lbv");
  const std::string words = std::to_string(vocabulary.num_words());
  const RunResult r = run("eval --model " + (dir_ / "model.lbm").string() + " --map " + map_.string() + " --report " +
                              (dir_ / "report_words.json").string() +
                              " --methods landmarkboost,landmarkboost_invfile --inverted-file-words " + words,
                          dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(dir_ / "report_words.json"));
  const nlohmann::json& parameters = report.at("settings").at("method_parameters");
  EXPECT_EQ(parameters.at("landmarkboost_invfile").at("inverted_file_words"), vocabulary.num_words());
  EXPECT_EQ(parameters.at("landmarkboost").at("inverted_file_words"), 0);  // dense: no words
  const nlohmann::json& dense = report.at("methods").at("landmarkboost");
  const nlohmann::json& inverted = report.at("methods").at("landmarkboost_invfile");
  for (const char* key : {"precision_at_1", "mrr", "match_precision", "match_recall", "accepted_matches_per_frame"}) {
    EXPECT_EQ(inverted.at(key), dense.at(key)) << key;
  }
  EXPECT_GT(dense.at("precision_at_1").get<double>(), 0.0);
  // One word (the default) is another ranking: fewer candidates.
  ASSERT_EQ(eval_.exit_code, 0) << eval_.err;
  const nlohmann::json one_word = nlohmann::json::parse(slurp(dir_ / "report.json"));
  const nlohmann::json& one = one_word.at("methods").at("landmarkboost_invfile");
  EXPECT_NE(one.at("mrr"), dense.at("mrr"));
  expect_eval_error(run("eval --model " + (dir_ / "model.lbm").string() + " --map " + map_.string() + " --report " +
                            (dir_ / "bad_report.json").string() + " --inverted-file-words 0",
                        dir_),
                    "eval: --inverted-file-words 0 must be in 1..256");
}

// `lboost localize` and `lboost eval` name the accepted matches' metrics alike and agree on them
// for the same model and options; localize no longer prints a "precision@1" of another definition.
TEST_F(EvalCliTest, LocalizeAndEvalShareMetricNames) {
  ASSERT_EQ(eval_.exit_code, 0) << eval_.err;
  const RunResult r = run("localize --model " + (dir_ / "model.lbm").string() + " --map " + map_.string() + " --out " +
                              (dir_ / "poses.json").string() + " --top-k 20",
                          dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out.find("precision@1"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("match recall"), std::string::npos) << r.out;
  const nlohmann::json summary = nlohmann::json::parse(slurp(dir_ / "poses.json")).at("summary");
  const nlohmann::json report = nlohmann::json::parse(slurp(dir_ / "report.json"));
  const nlohmann::json& lb = report.at("methods").at("landmarkboost");
  for (const char* key : {"match_recall", "match_precision", "background_rejection_rate"}) {
    EXPECT_DOUBLE_EQ(summary.at(key).get<double>(), lb.at(key).get<double>()) << key;
  }
  EXPECT_EQ(summary.at("keypoints_with_class_truth"), report.at("dataset").at("query_keypoints_with_class_truth"));
  EXPECT_FALSE(summary.contains("precision_at_1"));
  EXPECT_GT(summary.at("background_rejection_rate").get<double>(), 0.0);  // the default margin 0 rejects
  // Without rejection the accepted match is the top-ranked landmark: localize's match recall is
  // then eval's precision@1, and -inf is written as a string.
  const RunResult inf = run("localize --model " + (dir_ / "model.lbm").string() + " --map " + map_.string() +
                                " --out " + (dir_ / "poses_inf.json").string() + " --top-k 20 --min-margin -inf",
                            dir_);
  ASSERT_EQ(inf.exit_code, 0) << inf.err;
  const nlohmann::json poses_inf = nlohmann::json::parse(slurp(dir_ / "poses_inf.json"));
  EXPECT_EQ(poses_inf.at("options").at("min_margin"), "-inf");
  EXPECT_DOUBLE_EQ(poses_inf.at("summary").at("match_recall").get<double>(), lb.at("precision_at_1").get<double>());
  EXPECT_EQ(poses_inf.at("summary").at("background_rejection_rate").get<double>(), 0.0);
}

// `lboost localize --map` tracks each query session as a walk after localizing its frames: the
// walk verdicts and every pose are the same on 1 and 4 threads (timings aside); a frame the frame
// rule reports is reported by the walk too unless it disagrees with the frame before, a frame only
// the walk rule reports continues a trusted pose, and the summary counts what the frames say.
TEST_F(EvalCliTest, WalksAreTheSameOnOneAndFourThreads) {
  std::vector<nlohmann::json> frames;
  nlohmann::json summary;
  for (int threads : {1, 4}) {
    const fs::path out = dir_ / ("poses_threads" + std::to_string(threads) + ".json");
    const RunResult r = run("localize --model " + (dir_ / "model.lbm").string() + " --map " + map_.string() +
                                " --threads " + std::to_string(threads) + " --out " + out.string(),
                            dir_);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("tracked as walks"), std::string::npos) << r.out;
    nlohmann::json poses = nlohmann::json::parse(slurp(out));
    for (nlohmann::json& f : poses.at("frames")) f.erase("timings_ms");
    frames.push_back(poses.at("frames"));
    summary = poses.at("summary");
  }
  ASSERT_EQ(frames[0], frames[1]);
  int localized = 0, by_walk = 0, disagreeing = 0;
  for (const nlohmann::json& f : frames[0]) {
    const nlohmann::json& w = f.at("walk");
    const bool refused = w.at("agreement_applies").get<bool>() && w.at("agrees") == false;
    EXPECT_TRUE(!w.at("agreement_applies").get<bool>() || !w.at("agrees").is_null()) << f.at("name");
    if (f.at("success").get<bool>()) {
      EXPECT_EQ(w.at("localized").get<bool>(), !refused) << f.at("name");
    }
    if (refused) {
      EXPECT_FALSE(w.at("localized").get<bool>()) << f.at("name");
    }
    disagreeing += refused;
    if (w.at("by_walk_rule").get<bool>()) {
      EXPECT_FALSE(f.at("success").get<bool>()) << f.at("name");
      EXPECT_TRUE(w.at("continues").get<bool>()) << f.at("name");
      EXPECT_TRUE(f.at("pose_found").get<bool>()) << f.at("name");
    }
    if (w.at("localized").get<bool>()) {
      EXPECT_TRUE(f.at("pose_found").get<bool>()) << f.at("name");
    }
    localized += w.at("localized").get<bool>();
    by_walk += w.at("by_walk_rule").get<bool>();
  }
  EXPECT_EQ(summary.at("walk").at("localized"), localized);
  EXPECT_EQ(summary.at("walk").at("by_walk_rule"), by_walk);
  EXPECT_EQ(summary.at("walk").at("disagreeing"), disagreeing);
  EXPECT_GE(localized + disagreeing, summary.at("localized").get<int>());
}

// Every field report.json carries is documented in docs/report.md, and every documented field is
// written (method names, landmark-free keys and the copied training summary aside).
TEST_F(EvalCliTest, ReportSchemaIsDocumented) {
  ASSERT_EQ(eval_.exit_code, 0) << eval_.err;
  const char* source = std::getenv("LMB_SOURCE_DIR");
  ASSERT_NE(source, nullptr);
  const std::string doc = slurp(fs::path(source) / "docs" / "report.md");
  ASSERT_FALSE(doc.empty());
  std::set<std::string> documented;
  std::istringstream lines(doc);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.rfind("| `", 0) != 0) continue;
    const size_t end = line.find('`', 3);
    if (end != std::string::npos) documented.insert(line.substr(3, end - 3));
  }
  std::set<std::string> written;
  report_paths(nlohmann::json::parse(slurp(dir_ / "report.json")), "", written);
  for (const std::string& p : written) EXPECT_TRUE(documented.count(p)) << "undocumented report field " << p;
  for (const std::string& p : documented) EXPECT_TRUE(written.count(p)) << "documented but not written: " << p;
  // Every column of the printed results table is explained in the text report's section.
  const size_t section = doc.find("## The text report");
  ASSERT_NE(section, std::string::npos);
  const std::string text_doc = doc.substr(section, doc.find("\n## ", section + 1) - section);
  std::istringstream out(eval_.out);
  std::string header;
  while (std::getline(out, header) && header.rfind("method ", 0) != 0) {
  }
  std::istringstream columns(header);
  std::string column;
  int num_columns = 0;
  while (columns >> column) {
    ++num_columns;
    EXPECT_NE(text_doc.find("| " + column + " |"), std::string::npos) << "undocumented column " << column;
  }
  EXPECT_EQ(num_columns, 14) << header;
  // The CLI points to it in user words (no file paths), the job by its path; neither to a design
  // document outside the repository.
  const RunResult help = run("eval --help", dir_);
  EXPECT_NE(help.out.find("documentation's report page"), std::string::npos) << help.out;
  EXPECT_EQ(help.out.find("DESIGN.md"), std::string::npos) << help.out;
  const std::string job = slurp(fs::path(source) / "jobs" / "eval.sh");
  EXPECT_NE(job.find("docs/report.md"), std::string::npos);
  EXPECT_EQ(job.find("DESIGN.md"), std::string::npos);
  // --min-margin's default 0 rejects (the run above measured it); the help and the docs say so
  // rather than "no background rejection unless --min-margin".
  EXPECT_NE(help.out.find("the default 0 rejects"), std::string::npos) << help.out;
  for (const char* page : {"README.md", "docs/evaluation.md", "docs/report.md"}) {
    const std::string text = slurp(fs::path(source) / page);
    EXPECT_EQ(text.find("rejection unless"), std::string::npos) << page;
    EXPECT_EQ(text.find("DESIGN.md"), std::string::npos) << page;
  }
}

// The pose calibration: export fits it deterministically (a second export is the same file) and
// stores it (the model is calibrated); eval fits every method's the same way on map frames and
// its calibrated rule is exactly the frames whose probability reaches the threshold among the
// frames the inlier rule localizes, counted right by the per-frame flags.
TEST_F(EvalCliTest, PoseCalibrationIsDeterministicStoredAndCountedByEval) {
  ASSERT_EQ(eval_.exit_code, 0) << eval_.err;
  const auto model = Model::load(dir_ / "model.lbm");
  ASSERT_TRUE(model->calibrated());
  EXPECT_EQ(model->calibration().target_precision, 0.95);
  EXPECT_GT(model->calibration().num_samples, 0);
  const RunResult again = run("export --run " + (dir_ / "run").string() + " --map " + map_.string() + " --vocab " +
                                  (dir_ / "vocab.lbv").string() + " --out " + (dir_ / "model_again.lbm").string(),
                              dir_);
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(slurp(dir_ / "model_again.lbm"), slurp(dir_ / "model.lbm"));
  // --calibration off: the model as before this format (version 1 or 2), uncalibrated.
  const RunResult off =
      run("export --run " + (dir_ / "run").string() + " --map " + map_.string() + " --vocab " +
              (dir_ / "vocab.lbv").string() + " --out " + (dir_ / "model_off.lbm").string() + " --calibration off",
          dir_);
  ASSERT_EQ(off.exit_code, 0) << off.err;
  EXPECT_FALSE(Model::load(dir_ / "model_off.lbm")->calibrated());
  EXPECT_LT(slurp(dir_ / "model_off.lbm").size(), slurp(dir_ / "model.lbm").size());

  const nlohmann::json report = nlohmann::json::parse(slurp(dir_ / "report.json"));
  EXPECT_TRUE(report.at("model_calibration").at("calibrated").get<bool>());
  for (const auto& [name, m] : report.at("methods").items()) {
    const nlohmann::json& c = m.at("pose_confidence");
    EXPECT_EQ(c.at("inlier_rule").at("frames_localized"), m.at("frames_localized")) << name;
    EXPECT_EQ(c.at("inlier_rule").at("frames_correct"), m.at("frames_correct")) << name;
    const nlohmann::json& fit = c.at("calibration");
    EXPECT_GT(fit.at("frames").get<int>(), 0) << name;
    if (!fit.at("fitted").get<bool>()) continue;
    const double threshold = c.at("calibrated_rule").at("threshold").get<double>();
    const nlohmann::json& p = c.at("frame_confidence");
    const nlohmann::json& localized = m.at("per_frame").at("localized");
    const nlohmann::json& correct = m.at("per_frame").at("correct");
    ASSERT_EQ(p.size(), localized.size()) << name;
    int64_t reported = 0, right = 0;
    for (size_t i = 0; i < p.size(); ++i) {
      EXPECT_GE(p[i].get<double>(), 0.0);
      EXPECT_LT(p[i].get<double>(), 1.0);
      if (localized[i].get<int>() == 0 || p[i].get<double>() < threshold) continue;
      ++reported;
      right += correct[i].get<int>();
    }
    EXPECT_EQ(c.at("calibrated_rule").at("frames_localized").get<int64_t>(), reported) << name;
    EXPECT_EQ(c.at("calibrated_rule").at("frames_correct").get<int64_t>(), right) << name;
    EXPECT_LE(reported, m.at("frames_localized").get<int64_t>()) << name;
  }
  // LandmarkBoost's calibration in eval is the model's (the same frames, options and seed).
  const nlohmann::json& lb = report.at("methods").at("landmarkboost").at("pose_confidence").at("calibration");
  if (lb.at("fitted").get<bool>()) {
    EXPECT_EQ(lb.at("threshold").get<double>(), model->calibration().threshold);
    EXPECT_EQ(lb.at("bias").get<double>(), model->calibration().bias);
  }
  EXPECT_NE(eval_.out.find("success of reported poses"), std::string::npos) << eval_.out;
}

// Walks: every calibrated method's query session is tracked with each seed of the sweep. The frame
// rule over the walk is the calibrated rule the sweep counts at the default budget (the same poses);
// the walk verdict keeps every pose the frame rule reports unless it disagrees with the frame
// before, so with the poses it refused it reports at least as many; the export stores the walk
// calibration eval fits for LandmarkBoost.
TEST_F(EvalCliTest, WalksCountTheFrameRuleAndTheWalkRule) {
  ASSERT_EQ(eval_.exit_code, 0) << eval_.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(dir_ / "report.json"));
  int walks = 0;
  for (const auto& [name, m] : report.at("methods").items()) {
    const nlohmann::json& c = m.at("pose_confidence");
    if (!c.at("calibration").at("fitted").get<bool>()) {
      EXPECT_FALSE(c.contains("walk")) << name;
      continue;
    }
    ++walks;
    const nlohmann::json& w = c.at("walk");
    const nlohmann::json& seeds = w.at("seeds");
    ASSERT_EQ(seeds, m.at("pose_recall_sweep").at("seeds")) << name;
    const nlohmann::json* at_default = nullptr;
    for (const nlohmann::json& b : c.at("sweep")) {
      if (b.value("default_budget", false)) at_default = &b;
    }
    ASSERT_NE(at_default, nullptr) << name;
    int64_t frames = 0;
    for (const nlohmann::json& session : w.at("walks")) {
      frames += session.at("seeds")[0].at("walk_rule").at("frames").get<int64_t>();
    }
    EXPECT_EQ(frames, c.at("frames").get<int64_t>()) << name;  // every query frame, once
    for (size_t s = 0; s < seeds.size(); ++s) {
      const nlohmann::json& total = w.at("total")[s];
      const nlohmann::json& frame_rule = total.at("frame_rule");
      const nlohmann::json& walk_rule = total.at("walk_rule");
      const nlohmann::json& swept = at_default->at("seeds")[s].at("calibrated_rule");
      EXPECT_EQ(frame_rule.at("reported"), swept.at("frames_localized")) << name << " seed " << s;
      EXPECT_EQ(frame_rule.at("reported_right"), swept.at("frames_correct")) << name << " seed " << s;
      EXPECT_GE(walk_rule.at("reported").get<int64_t>() + walk_rule.at("disagreeing").get<int64_t>(),
                frame_rule.at("reported").get<int64_t>())
          << name;
      EXPECT_EQ(frame_rule.at("disagreeing"), 0) << name;
      EXPECT_EQ(walk_rule.at("frames_right"), frame_rule.at("frames_right")) << name;
      EXPECT_GT(walk_rule.at("mean_ms").get<double>(), 0.0) << name;
    }
  }
  EXPECT_GT(walks, 0);
  const auto model = Model::load(dir_ / "model.lbm");
  const nlohmann::json& lb = report.at("methods").at("landmarkboost").at("pose_confidence");
  if (lb.contains("walk") && lb.at("walk").at("calibration").at("fitted").get<bool>()) {
    ASSERT_TRUE(model->walk_calibration().has_value());
    EXPECT_EQ(model->walk_calibration()->threshold, lb.at("walk").at("calibration").at("threshold").get<double>());
    EXPECT_EQ(model->walk_calibration()->bias, lb.at("walk").at("calibration").at("bias").get<double>());
    const nlohmann::json& agreement = lb.at("walk").at("calibration").at("agreement");
    EXPECT_EQ(model->walk_calibration()->has_agreement(), !agreement.is_null());
    if (!agreement.is_null()) {
      EXPECT_EQ(model->walk_calibration()->agreement_noise_m, agreement.at("noise_m").get<double>());
      EXPECT_EQ(model->walk_calibration()->agreement_step_deg, agreement.at("step_deg").get<double>());
    }
  }
  EXPECT_NE(eval_.out.find("walks (each query session tracked"), std::string::npos) << eval_.out;
}

// The classes of the model and the training observations of a map (every observation of a class
// landmark in a map frame), less `excluded` (sorted keypoints).
std::vector<char> class_flags(const LandmarkMap& map, const Model& model) {
  std::vector<char> is_class(map.landmarks.size(), 0);
  for (int32_t c = 0; c < model.num_classes(); ++c) is_class[model.class_landmark(c)] = 1;
  return is_class;
}
std::vector<int64_t> class_observations(const LandmarkMap& map, const std::vector<char>& is_class,
                                        const std::vector<int64_t>& excluded) {
  std::vector<int64_t> out;
  for (const MapFrame& f : map.frames) {
    if (f.is_query) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[k];
      if (l >= 0 && is_class[l] && !std::binary_search(excluded.begin(), excluded.end(), k)) out.push_back(k);
    }
  }
  return out;
}
// Precision@1 of exact Hamming 1-NN (ties: the first observation in map order) of `queries` (map
// keypoints whose true landmark is a class) against the observations `train`.
double hamming_p1(const LandmarkMap& map, const std::vector<int64_t>& queries, const std::vector<int64_t>& train) {
  int64_t correct = 0;
  for (int64_t k : queries) {
    int best = 1 << 30;
    landmark_t best_landmark = -1;
    for (int64_t t : train) {
      const int d = hamming_distance(map.descriptor(k), map.descriptor(t), map.descriptor_bytes);
      if (d < best) {
        best = d;
        best_landmark = map.keypoint_landmark[t];
      }
    }
    correct += best_landmark == map.keypoint_landmark[k];
  }
  return static_cast<double>(correct) / static_cast<double>(queries.size());
}
// The keypoints of the frames of `session` whose true landmark is a class.
std::vector<int64_t> session_keypoints(const LandmarkMap& map, const std::vector<char>& is_class, int32_t session) {
  std::vector<int64_t> out;
  for (const MapFrame& f : map.frames) {
    if (f.session != session) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[k];
      if (l >= 0 && is_class[l]) out.push_back(k);
    }
  }
  return out;
}

// With --run, the observations the run held out of training (its config.toml) are ranked:
// exactly held_out_observations' keypoints, bruteforce_hamming searching the map observations
// without them (equal to a nearest neighbour computed here), next to the query session in
// generalization_gap and in the printed table.
TEST_F(EvalCliTest, HeldOutMapObservationsBesideTheQuerySession) {
  ASSERT_EQ(eval_.exit_code, 0) << eval_.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(dir_ / "report.json"));
  const LandmarkMap map = read_map_h5(map_);
  const std::shared_ptr<const Model> model = Model::load(dir_ / "model.lbm");
  const std::vector<char> is_class = class_flags(map, *model);
  std::vector<landmark_t> classes;
  for (int32_t c = 0; c < model->num_classes(); ++c) classes.push_back(model->class_landmark(c));
  const TrainingSetOptions options = read_train_config(dir_ / "run" / "config.toml").training_set;
  const std::vector<int64_t> held = held_out_observations(map, classes, options);
  ASSERT_GT(held.size(), 10u);
  std::set<frame_t> held_frames;
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    const MapFrame& frame = map.frames[f];
    for (int64_t k : held) {
      if (k >= frame.first_keypoint && k < frame.first_keypoint + frame.num_keypoints) {
        EXPECT_FALSE(frame.is_query);
        held_frames.insert(f);
      }
    }
  }
  const nlohmann::json& h = report.at("held_out_map_observations");
  EXPECT_EQ(h.at("keypoints").get<size_t>(), held.size());
  EXPECT_EQ(h.at("frames").get<size_t>(), held_frames.size());
  EXPECT_EQ(h.at("validation_fraction").get<double>(), options.validation_fraction);
  EXPECT_EQ(h.at("methods").size(), 7u);
  const double reference = hamming_p1(map, held, class_observations(map, is_class, held));
  EXPECT_DOUBLE_EQ(h.at("methods").at("bruteforce_hamming").at("precision_at_1").get<double>(), reference);
  // Searching the held-out observations themselves would find each at distance 0.
  EXPECT_LT(reference, 1.0);
  const nlohmann::json& gap = report.at("generalization_gap").at("precision_at_1");
  for (const auto& [name, m] : report.at("methods").items()) {
    SCOPED_TRACE(name);
    EXPECT_EQ(gap.at(name).at("held_out_map_observations"), h.at("methods").at(name).at("precision_at_1"));
    EXPECT_EQ(gap.at(name).at("sessions").at("query"), m.at("precision_at_1"));
  }
  EXPECT_NE(
      eval_.out.find("generalization gap: held-out map observations (" + std::to_string(held.size()) + " keypoints"),
      std::string::npos)
      << eval_.out;
}

// The fused model ranks held-out map observations without their own descriptors among the
// fusion's exemplars (which hold every map observation): each class keeps exactly its
// observations outside the held-out ones, in map order. A model whose exemplars are not the map's
// is refused.
TEST_F(EvalCliTest, HeldOutObservationsAreNotTheirOwnFusionExemplars) {
  const LandmarkMap map = read_map_h5(map_);
  const std::shared_ptr<const Model> model = Model::load(dir_ / "model.lbm");
  ASSERT_TRUE(model->data().fusion.enabled());  // export fuses by default
  std::vector<landmark_t> classes;
  for (int32_t c = 0; c < model->num_classes(); ++c) classes.push_back(model->class_landmark(c));
  const std::vector<int64_t> held =
      held_out_observations(map, classes, read_train_config(dir_ / "run" / "config.toml").training_set);
  ASSERT_GT(held.size(), 10u);
  EXPECT_EQ(without_exemplars(model, map, {}), model);
  const std::shared_ptr<const Model> stripped = without_exemplars(model, map, held);
  const DescriptorFusion& f = stripped->data().fusion;
  const int bytes = map.descriptor_bytes;
  const std::vector<int64_t> kept = class_observations(map, class_flags(map, *model), held);
  ASSERT_EQ(static_cast<int64_t>(f.exemplars.size()), static_cast<int64_t>(kept.size()) * bytes);
  ASSERT_EQ(f.exemplars.size() + held.size() * bytes, model->data().fusion.exemplars.size());
  for (int32_t c = 0; c < model->num_classes(); ++c) {
    std::vector<int64_t> own;
    for (int64_t k : kept) {
      if (map.keypoint_landmark[k] == model->class_landmark(c)) own.push_back(k);
    }
    ASSERT_EQ(f.exemplar_begin[c + 1] - f.exemplar_begin[c], static_cast<int64_t>(own.size())) << "class " << c;
    for (size_t i = 0; i < own.size(); ++i) {
      EXPECT_TRUE(std::equal(map.descriptor(own[i]), map.descriptor(own[i]) + bytes,
                             f.exemplars.begin() + (f.exemplar_begin[c] + static_cast<int64_t>(i)) * bytes));
    }
  }
  EXPECT_EQ(stripped->data().stumps.size(), model->data().stumps.size());
  EXPECT_EQ(stripped->data().fusion.distance_score, model->data().fusion.distance_score);

  LandmarkMap other = map;
  other.descriptors[static_cast<size_t>(kept.front() * bytes)] ^= 1;
  EXPECT_THROW(without_exemplars(model, other, held), Error);

  // A model whose exemplars are a subset of the map's observations (export --max-exemplars): each
  // class's first observation outside the held-out ones and its first held-out one (if any), the
  // held-out rows removed.
  ModelData subset = model->data();
  subset.fusion.exemplars.clear();
  subset.fusion.exemplar_begin.assign(1, 0);
  std::vector<uint8_t> expected;
  std::vector<int64_t> expected_begin = {0};
  const std::vector<std::vector<int64_t>> of = exemplar_keypoints(map, classes);
  int64_t held_rows = 0;
  for (int32_t c = 0; c < model->num_classes(); ++c) {
    std::vector<int64_t> rows;
    for (bool want_held : {false, true}) {
      for (int64_t k : of[c]) {
        if (std::binary_search(held.begin(), held.end(), k) == want_held) {
          rows.push_back(k);
          break;
        }
      }
    }
    ASSERT_FALSE(rows.empty());
    std::sort(rows.begin(), rows.end());
    for (int64_t k : rows) {
      subset.fusion.exemplars.insert(subset.fusion.exemplars.end(), map.descriptor(k), map.descriptor(k) + bytes);
      if (std::binary_search(held.begin(), held.end(), k)) {
        ++held_rows;
      } else {
        expected.insert(expected.end(), map.descriptor(k), map.descriptor(k) + bytes);
      }
    }
    subset.fusion.exemplar_begin.push_back(static_cast<int64_t>(subset.fusion.exemplars.size()) / bytes);
    expected_begin.push_back(static_cast<int64_t>(expected.size()) / bytes);
  }
  ASSERT_GT(held_rows, 0);
  const std::shared_ptr<const Model> subset_model = std::make_shared<const Model>(subset);
  const std::shared_ptr<const Model> subset_stripped = without_exemplars(subset_model, map, held);
  EXPECT_EQ(subset_stripped->data().fusion.exemplars, expected);
  EXPECT_EQ(subset_stripped->data().fusion.exemplar_begin, expected_begin);
  LandmarkMap moved = map;  // the descriptor of a stored row changed
  moved.descriptors[static_cast<size_t>(kept.front() * bytes)] ^= 1;
  EXPECT_THROW(without_exemplars(subset_model, moved, held), Error);

  // Every observation of class 0 excluded (a landmark seen only in the pose calibration's frames):
  // refused, or with keep_sole the class keeps its exemplars while the others lose theirs.
  std::vector<int64_t> sole = held;
  sole.insert(sole.end(), of[0].begin(), of[0].end());
  std::sort(sole.begin(), sole.end());
  sole.erase(std::unique(sole.begin(), sole.end()), sole.end());
  EXPECT_THROW(without_exemplars(model, map, sole), Error);
  const DescriptorFusion& whole = model->data().fusion;
  const std::shared_ptr<const Model> sole_model = without_exemplars(model, map, sole, /*keep_sole=*/true);
  const DescriptorFusion& kept_sole = sole_model->data().fusion;
  EXPECT_EQ(kept_sole.exemplar_begin[1], whole.exemplar_begin[1]);
  EXPECT_TRUE(std::equal(kept_sole.exemplars.begin(), kept_sole.exemplars.begin() + whole.exemplar_begin[1] * bytes,
                         whole.exemplars.begin()));
  for (int32_t c = 1; c < model->num_classes(); ++c) {
    EXPECT_EQ(kept_sole.exemplar_begin[c + 1] - kept_sole.exemplar_begin[c],
              f.exemplar_begin[c + 1] - f.exemplar_begin[c])
        << "class " << c;
  }
}

// A run that holds map frames out for the pose calibration (here 6, at most half of the tiny
// map's frames, at least 2): train names their count, none of them is a training sample, export and
// eval fit the calibration on exactly them (the log lines and the fitted poses say so), and
// eval --run uses the run's hold-out.
TEST_F(EvalCliTest, TheFramesTrainingHeldOutAreTheCalibrationFrames) {
  const fs::path run_dir = dir_ / "run_holdout", config = dir_ / "holdout.toml", model = dir_ / "holdout.lbm";
  {
    std::ofstream(config) << "[training_set]\ncalibration_frames = 6\ncalibration_frame_share = 0.5\n"
                             "min_calibration_frames = 2\n";
  }
  const std::string m = " --map " + map_.string() + " --vocab " + (dir_ / "vocab.lbv").string();
  const RunResult train = run("train" + m + " --config " + config.string() + " --out " + run_dir.string() +
                                  " --rounds 10 --dims-per-round 100 --threads 2",
                              dir_);
  ASSERT_EQ(train.exit_code, 0) << train.err;
  const LandmarkMap map = read_map_h5(map_);
  const TrainConfig c = read_run_train_config(run_dir / "config.toml");
  EXPECT_EQ(c.training_set.calibration_frames, 6);
  const std::vector<frame_t> held = calibration_holdout_frames(map, c.training_set);
  ASSERT_EQ(held.size(), 6u);
  EXPECT_NE((train.out + train.err).find("train: 6 map frames held out whole for the pose calibration"),
            std::string::npos)
      << train.err;
  const RunResult exported = run("export --run " + run_dir.string() + m + " --out " + model.string(), dir_);
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  EXPECT_NE((exported.out + exported.err).find("pose calibration on 6 map frames held out of training"),
            std::string::npos)
      << exported.err;
  const std::shared_ptr<const Model> loaded = Model::load(model);
  ASSERT_TRUE(loaded->calibrated());
  EXPECT_LE(loaded->calibration().num_samples, 12);  // two poses a frame at most
  EXPECT_GT(loaded->calibration().num_samples, 0);
  const RunResult evaluated =
      run("eval --model " + model.string() + " --map " + map_.string() + " --run " + run_dir.string() +
              " --methods landmarkboost --report " + (dir_ / "holdout.json").string(),
          dir_);
  ASSERT_EQ(evaluated.exit_code, 0) << evaluated.err;
  EXPECT_NE((evaluated.out + evaluated.err).find("pose calibration on 6 map frames held out of training by the run"),
            std::string::npos)
      << evaluated.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(dir_ / "holdout.json"));
  EXPECT_EQ(report.at("methods").at("landmarkboost").at("pose_confidence").at("calibration").at("frames"), 6);
}

// The fixture's tiny world is too small to hold calibration frames out (the default options), so
// its run is cross-fitted: train says so and trains the five fold models into run/folds/k, each
// without every 5th map frame from position k (its config.toml records the fold); export and eval
// fit the calibration on every map frame, each matched by the fold model that never saw it (the
// logs and the report say so, for every method); eval without --vocab and a fold trained with
// other settings are one-line errors.
TEST_F(EvalCliTest, ASmallMapIsCalibratedByCrossFitting) {
  const LandmarkMap map = read_map_h5(map_);
  const TrainConfig c = read_run_train_config(dir_ / "run" / "config.toml");
  ASSERT_TRUE(calibration_holdout_frames(map, c.training_set).empty());
  ASSERT_EQ(cross_fitting_folds(map, c.training_set), 5);
  for (int32_t k = 0; k < 5; ++k) {
    const fs::path fold = dir_ / "run" / "folds" / std::to_string(k);
    ASSERT_TRUE(fs::exists(fold / "model.bin")) << fold;
    const TrainConfig fc = read_run_train_config(fold / "config.toml");
    EXPECT_EQ(fc.training_set.calibration_fold, k);
    EXPECT_EQ(calibration_holdout_frames(map, fc.training_set), calibration_fold_frames(map, 5, k));
  }
  EXPECT_NE(slurp(dir_ / "run" / "log.txt").find("the pose calibration is cross-fitted on 5 fold models"),
            std::string::npos);
  EXPECT_NE((eval_.out + eval_.err)
                .find("landmarkboost: pose calibration on " + std::to_string(map.map_session_frames().size()) +
                      " map frames, cross-fitted on the run's 5 fold models"),
            std::string::npos)
      << eval_.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(dir_ / "report.json"));
  for (const auto& [name, m] : report.at("methods").items()) {
    const nlohmann::json& cal = m.at("pose_confidence").at("calibration");
    EXPECT_EQ(cal.at("frames_source"), "cross_fitted") << name;
    EXPECT_EQ(cal.at("frames"), static_cast<int64_t>(map.map_session_frames().size())) << name;
  }
  const std::string m = " --map " + map_.string();
  const RunResult exported = run("export --run " + (dir_ / "run").string() + m + " --vocab " +
                                     (dir_ / "vocab.lbv").string() + " --out " + (dir_ / "crossed.lbm").string(),
                                 dir_);
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  EXPECT_NE((exported.out + exported.err).find("cross-fitted (each of 5 folds matched by the fold model"),
            std::string::npos)
      << exported.err;
  expect_eval_error(run("eval --model " + (dir_ / "model.lbm").string() + m + " --run " + (dir_ / "run").string() +
                            " --methods landmarkboost --report " + (dir_ / "novocab.json").string(),
                        dir_),
                    "give --vocab");
  EXPECT_FALSE(fs::exists(dir_ / "novocab.json"));
  // A fold trained with other settings is refused, naming it.
  const fs::path copy = dir_ / "run_copy";
  fs::copy(dir_ / "run", copy, fs::copy_options::recursive);
  {
    std::string text = slurp(copy / "folds" / "1" / "config.toml");
    const size_t at = text.find("num_rounds = ");
    ASSERT_NE(at, std::string::npos);
    text.replace(at, text.find('\n', at) - at, "num_rounds = 7");
    std::ofstream(copy / "folds" / "1" / "config.toml") << text;
  }
  const RunResult refused = run("export --run " + copy.string() + m + " --vocab " + (dir_ / "vocab.lbv").string() +
                                    " --out " + (dir_ / "refused.lbm").string(),
                                dir_);
  test::expect_one_error(refused, "export", "fold 1 was trained with other settings");
  EXPECT_FALSE(fs::exists(dir_ / "refused.lbm"));
  fs::remove_all(copy);
}

// export --max-exemplars N keeps at most N exemplars a class, each a map observation of its class
// outside the held-out ones (k_centre_exemplars of them, tested against a brute force in
// descriptor_fusion_test); the model is smaller, eval ranks its held-out observations with it, and
// a negative N is a one-line error that writes nothing.
TEST_F(EvalCliTest, ExportMaxExemplarsKeepsAtMostThatManyAClass) {
  const std::string base = "export --run " + (dir_ / "run").string() + " --map " + map_.string() + " --vocab " +
                           (dir_ / "vocab.lbv").string() + " --calibration off";
  const RunResult capped = run(base + " --max-exemplars 2 --out " + (dir_ / "model_cap2.lbm").string(), dir_);
  ASSERT_EQ(capped.exit_code, 0) << capped.err;
  const LandmarkMap map = read_map_h5(map_);
  const auto model = Model::load(dir_ / "model_cap2.lbm");
  const DescriptorFusion& f = model->data().fusion;
  ASSERT_TRUE(f.enabled());
  std::vector<landmark_t> classes;
  for (int32_t c = 0; c < model->num_classes(); ++c) classes.push_back(model->class_landmark(c));
  const std::vector<int64_t> held =
      held_out_observations(map, classes, read_train_config(dir_ / "run" / "config.toml").training_set);
  const std::vector<std::vector<int64_t>> of = exemplar_keypoints(map, classes);
  const int bytes = map.descriptor_bytes;
  int64_t full = 0;
  for (int32_t c = 0; c < model->num_classes(); ++c) {
    const int64_t rows = f.exemplar_begin[c + 1] - f.exemplar_begin[c];
    EXPECT_GE(rows, 1);
    EXPECT_LE(rows, 2) << "class " << c;
    full += static_cast<int64_t>(of[c].size());
    for (int64_t r = f.exemplar_begin[c]; r < f.exemplar_begin[c + 1]; ++r) {
      const uint8_t* row = f.exemplars.data() + r * bytes;
      bool found = false;
      for (int64_t k : of[c]) {
        if (!std::binary_search(held.begin(), held.end(), k) && std::equal(row, row + bytes, map.descriptor(k))) {
          found = true;
        }
      }
      EXPECT_TRUE(found) << "class " << c << " row " << r
                         << " is no observation of its class outside the held-out ones";
    }
  }
  EXPECT_LT(f.exemplar_begin.back(), full);
  const RunResult ev = run("eval --model " + (dir_ / "model_cap2.lbm").string() + " --map " + map_.string() +
                               " --run " + (dir_ / "run").string() + " --vocab " + (dir_ / "vocab.lbv").string() +
                               " --methods landmarkboost --report " + (dir_ / "report_cap2.json").string(),
                           dir_);
  ASSERT_EQ(ev.exit_code, 0) << ev.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(dir_ / "report_cap2.json"));
  EXPECT_GT(report.at("generalization_gap").at("precision_at_1").at("landmarkboost").at("held_out_map_observations"),
            0.0);
  const RunResult bad = run(base + " --max-exemplars -1 --out " + (dir_ / "model_bad.lbm").string(), dir_);
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("max_exemplars = -1 must be >= 0"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(dir_ / "model_bad.lbm"));
}

// The tiny map's query frames split into two query sessions (alternate frames) and an empty
// outside session: the methods' figures over both equal those of the unsplit map, each session's
// figures equal a reference computed on its frames alone, --query-session evaluates one session,
// and naming a map, outside or unknown session is a one-line error.
TEST_F(EvalCliTest, QuerySessionsAreReportedAndSelectedByName) {
  ASSERT_EQ(eval_.exit_code, 0) << eval_.err;
  LandmarkMap map = read_map_h5(map_);
  const int32_t query = map.find_session("query");
  ASSERT_GE(query, 0);
  map.sessions.push_back({"query-b", SessionKind::kQuery});
  map.sessions.push_back({"elsewhere", SessionKind::kOutside});
  int64_t frames_a = 0, frames_b = 0, n = 0;
  for (MapFrame& f : map.frames) {
    if (f.session != query) continue;
    if (n++ % 2 == 1) {
      f.session = static_cast<int32_t>(map.sessions.size()) - 2;
      ++frames_b;
    } else {
      ++frames_a;
    }
  }
  ASSERT_GT(frames_b, 0);
  const fs::path split = dir_ / "split.h5";
  write_map_h5(map, split);
  const std::string common = "eval --model " + (dir_ / "model.lbm").string() + " --map " + split.string() +
                             " --methods bruteforce_hamming,landmarkboost --report ";
  const RunResult both = run(common + (dir_ / "split_report.json").string(), dir_);
  ASSERT_EQ(both.exit_code, 0) << both.err;
  const nlohmann::json r = nlohmann::json::parse(slurp(dir_ / "split_report.json"));
  const nlohmann::json whole = nlohmann::json::parse(slurp(dir_ / "report.json"));
  EXPECT_EQ(r.at("dataset").at("query_sessions"), nlohmann::json({"query", "query-b"}));
  const nlohmann::json& sessions = r.at("sessions");
  ASSERT_EQ(sessions.size(), 2u);
  EXPECT_EQ(sessions[0].at("name"), "query");
  EXPECT_EQ(sessions[1].at("name"), "query-b");
  EXPECT_EQ(sessions[0].at("frames").get<int64_t>(), frames_a);
  EXPECT_EQ(sessions[1].at("frames").get<int64_t>(), frames_b);
  EXPECT_FALSE(r.contains("held_out_map_observations"));  // no --run
  const std::shared_ptr<const Model> model = Model::load(dir_ / "model.lbm");
  const std::vector<char> is_class = class_flags(map, *model);
  const std::vector<int64_t> train = class_observations(map, is_class, {});
  for (const char* name : {"bruteforce_hamming", "landmarkboost"}) {
    SCOPED_TRACE(name);
    const nlohmann::json& m = r.at("methods").at(name);
    const nlohmann::json& w = whole.at("methods").at(name);
    EXPECT_NEAR(m.at("precision_at_1").get<double>(), w.at("precision_at_1").get<double>(), 1e-12);
    EXPECT_NEAR(m.at("mrr").get<double>(), w.at("mrr").get<double>(), 1e-12);
    EXPECT_EQ(m.at("frames_correct"), w.at("frames_correct"));
    EXPECT_EQ(m.at("pose_recall_sweep").at("recall"), w.at("pose_recall_sweep").at("recall"));
    int64_t correct = 0, localized = 0;
    for (const nlohmann::json& s : sessions) {
      correct += s.at("methods").at(name).at("frames_correct").get<int64_t>();
      localized += s.at("methods").at(name).at("frames_localized").get<int64_t>();
      const nlohmann::json& gap = r.at("generalization_gap").at("precision_at_1").at(name);
      EXPECT_EQ(gap.at("sessions").at(s.at("name").get<std::string>()), s.at("methods").at(name).at("precision_at_1"));
      EXPECT_TRUE(gap.at("held_out_map_observations").is_null());
    }
    EXPECT_EQ(correct, m.at("frames_correct").get<int64_t>());
    EXPECT_EQ(localized, m.at("frames_localized").get<int64_t>());
  }
  for (int i = 0; i < 2; ++i) {
    const int32_t session = map.find_session(sessions[i].at("name").get<std::string>());
    const std::vector<int64_t> keypoints = session_keypoints(map, is_class, session);
    EXPECT_EQ(sessions[i].at("keypoints_with_class_truth").get<size_t>(), keypoints.size());
    EXPECT_DOUBLE_EQ(sessions[i].at("methods").at("bruteforce_hamming").at("precision_at_1").get<double>(),
                     hamming_p1(map, keypoints, train));
  }
  EXPECT_NE(both.out.find("query-b P@1"), std::string::npos) << both.out;

  // One session by name: its figures are that session's above.
  const RunResult one = run(common + (dir_ / "one_report.json").string() + " --query-session query-b", dir_);
  ASSERT_EQ(one.exit_code, 0) << one.err;
  const nlohmann::json o = nlohmann::json::parse(slurp(dir_ / "one_report.json"));
  EXPECT_EQ(o.at("dataset").at("query_sessions"), nlohmann::json({"query-b"}));
  EXPECT_EQ(o.at("dataset").at("query_frames").get<int64_t>(), frames_b);
  for (const char* name : {"bruteforce_hamming", "landmarkboost"}) {
    EXPECT_EQ(o.at("methods").at(name).at("precision_at_1"), sessions[1].at("methods").at(name).at("precision_at_1"));
    EXPECT_EQ(o.at("methods").at(name).at("frames_correct"), sessions[1].at("methods").at(name).at("frames_correct"));
  }

  const std::string bad = common + (dir_ / "bad_report.json").string() + " --query-session ";
  expect_eval_error(run(bad + "map", dir_), "'map': a map session");
  expect_eval_error(run(bad + "elsewhere", dir_), "'elsewhere': an outside session");
  expect_eval_error(run(bad + "nowhere", dir_), "'nowhere': " + split.string() + " has no such session");
  expect_eval_error(run(bad + "query,query", dir_), "'query' given twice");
  EXPECT_FALSE(fs::exists(dir_ / "bad_report.json"));
}

TEST_F(EvalCliTest, MismatchedInputsGiveOneLineErrors) {
  LandmarkMap map = read_map_h5(map_);
  const std::string model = " --model " + (dir_ / "model.lbm").string();
  const std::string report = " --report " + (dir_ / "bad_report.json").string();
  // A map whose landmarks moved: the model was trained on another map.
  LandmarkMap moved = map;
  for (Landmark& l : moved.landmarks) l.position.x() += 1.0;
  write_map_h5(moved, dir_ / "moved.h5");
  expect_eval_error(run("eval" + model + " --map " + (dir_ / "moved.h5").string() + report, dir_),
                    "trained on another map");
  // A map without query frames.
  LandmarkMap no_query = map;
  ASSERT_EQ(no_query.sessions.front().kind, SessionKind::kMap);
  no_query.sessions.resize(1);
  for (MapFrame& f : no_query.frames) {
    f.is_query = false;
    f.session = 0;
  }
  for (Landmark& l : no_query.landmarks) {
    l.num_map_observations += l.num_query_observations;
    l.num_query_observations = 0;
  }
  write_map_h5(no_query, dir_ / "no_query.h5");
  expect_eval_error(run("eval" + model + " --map " + (dir_ / "no_query.h5").string() + report, dir_),
                    "no query session");
  // An unknown method.
  expect_eval_error(run("eval" + model + " --map " + map_.string() + report + " --methods landmarkboost,faiss", dir_),
                    "unknown method 'faiss'");
  EXPECT_FALSE(fs::exists(dir_ / "bad_report.json"));
}

}  // namespace
}  // namespace lmb
