#include "train/eval/report.h"

#include <cmath>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

MethodResult sample_method(const std::string& name) {
  MethodResult r;
  r.name = name;
  KeypointRanking a;
  a.truth = 5;
  a.candidates = {{5, 1.0}, {7, 0.5}};
  KeypointRanking b;
  b.truth = 3;
  b.candidates = {{7, 1.0}, {3, 0.5}};
  r.retrieval = evaluate_retrieval({a, b});
  FrameOutcome ok;
  ok.localized = true;
  ok.confidence = 30;
  ok.num_correspondences = 60;
  ok.num_inliers = 30;
  ok.match_ms = 4.0;
  ok.total_ms = 6.0;
  FrameOutcome failed;
  failed.match_ms = 2.0;
  failed.total_ms = 8.0;
  r.frames = {ok, failed};
  r.pose = evaluate_poses(r.frames);
  return r;
}

TEST(BuildReport, DesignFieldsAndCurves) {
  DatasetCounts counts;
  counts.map_frames = 10;
  counts.query_frames = 2;
  counts.landmarks = 100;
  counts.query_keypoints = 3;
  counts.query_keypoints_with_truth = 2;
  const nlohmann::json report =
      build_report(counts, {sample_method("landmarkboost"), sample_method("bruteforce_hamming")});
  EXPECT_EQ(report["dataset"]["query_keypoints_with_truth"], 2);
  const auto& m = report["methods"]["landmarkboost"];
  EXPECT_DOUBLE_EQ(m["precision_at_1"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(m["mrr"].get<double>(), 0.75);
  // Curve: n = 1 -> fppi 0.5, miss 0.5; n = 2 -> fppi 1, miss 0: MR at FPPI 1 is 0.
  EXPECT_DOUBLE_EQ(m["miss_rate_at_fppi"]["1"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(m["miss_rate_at_fppi"]["0.1"].get<double>(), 1.0);
  EXPECT_EQ(m["miss_rate_curve"]["fppi"].size(), 3u);
  EXPECT_DOUBLE_EQ(m["pose_recall_20cm_5deg"].get<double>(), 0.5);
  // One correct frame of two: the curve is (0, 1), (0.5, 1), AUC 0.5.
  EXPECT_DOUBLE_EQ(m["pose_auc"].get<double>(), 0.5);
  EXPECT_EQ(m["pose_pr_curve"]["recall"].size(), 2u);
  EXPECT_DOUBLE_EQ(m["mean_inlier_ratio"].get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(m["match_ms_per_frame"].get<double>(), 3.0);
  EXPECT_DOUBLE_EQ(m["total_ms_per_frame"].get<double>(), 7.0);
  EXPECT_EQ(m["per_frame"]["localized"], nlohmann::json({1, 0}));
  EXPECT_TRUE(m["per_frame"]["position_error_m"][1].is_null());  // NaN -> null
  EXPECT_EQ(m["per_frame"]["match_ms"], nlohmann::json({4.0, 2.0}));
  for (const char* key : {"median_position_error_m", "median_rotation_error_deg", "log_average_miss_rate"}) {
    EXPECT_TRUE(m.contains(key)) << key;
  }

  const std::string table = format_results_table(report);
  EXPECT_NE(table.find("landmarkboost"), std::string::npos);
  EXPECT_NE(table.find("bruteforce_hamming"), std::string::npos);
  EXPECT_NE(table.find("0.5000"), std::string::npos);

  const auto path = std::filesystem::temp_directory_path() / "lmb_report_test.json";
  write_report(path, report);
  std::ifstream in(path);
  EXPECT_EQ(nlohmann::json::parse(in), report);
  std::filesystem::remove(path);
}

// The table's thresholds section: one column a --pose-thresholds pair, only when they are not
// just the default pair.
TEST(BuildReport, TableShowsRecallAtEachThresholdPair) {
  MethodResult r = sample_method("landmarkboost");
  r.recall_at_thresholds = {ThresholdRecall{PoseThresholds{}, 1, 0.5}};
  const std::string plain = format_results_table(build_report(DatasetCounts{}, {r}));
  EXPECT_EQ(plain.find("--pose-thresholds"), std::string::npos) << plain;
  EXPECT_NE(plain.find("rec20/5"), std::string::npos) << plain;
  r.recall_at_thresholds.push_back(ThresholdRecall{PoseThresholds{1.0, 2.0}, 2, 1.0});
  const std::string table = format_results_table(build_report(DatasetCounts{}, {r}));
  const size_t section = table.find("pose recall at each --pose-thresholds pair");
  ASSERT_NE(section, std::string::npos) << table;
  EXPECT_NE(table.find("0.2 m, 5 deg", section), std::string::npos) << table;
  EXPECT_NE(table.find("1 m, 2 deg", section), std::string::npos) << table;
  EXPECT_NE(table.find("landmarkboost                       0.5000            1.0000", section), std::string::npos)
      << table;
}

// The 7-Scenes fields: recall at 5 cm / 5 deg, and medians over all query frames, written as the
// string "inf" when half of the frames or more have no pose (JSON has no infinity) and null without
// frames; the table shows them in a section of their own.
TEST(BuildReport, SevenScenesFieldsOverAllFrames) {
  MethodResult r = sample_method("landmarkboost");  // one frame at the truth, one not localized
  nlohmann::json m = build_report(DatasetCounts{}, {r})["methods"]["landmarkboost"];
  EXPECT_DOUBLE_EQ(m["pose_recall_5cm_5deg"].get<double>(), 0.5);
  EXPECT_EQ(m["median_position_error_all_frames_m"], "inf");
  EXPECT_EQ(m["median_rotation_error_all_frames_deg"], "inf");
  std::string table = format_results_table(build_report(DatasetCounts{}, {r}));
  const size_t section = table.find("pose over all query frames, the 7-Scenes convention");
  ASSERT_NE(section, std::string::npos) << table;
  EXPECT_NE(table.find("landmarkboost              0.5000           inf           inf", section), std::string::npos)
      << table;

  // Three frames, two of them at the truth: the median is the localized frames' 0.
  r.frames.push_back(r.frames.front());
  r.pose = evaluate_poses(r.frames);
  m = build_report(DatasetCounts{}, {r})["methods"]["landmarkboost"];
  EXPECT_DOUBLE_EQ(m["median_position_error_all_frames_m"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(m["median_rotation_error_all_frames_deg"].get<double>(), 0.0);
  table = format_results_table(build_report(DatasetCounts{}, {r}));
  EXPECT_NE(table.find("landmarkboost              0.6667         0.000         0.000"), std::string::npos) << table;

  // No query frame: null, "-" in the table.
  r.frames.clear();
  r.pose = evaluate_poses({});
  m = build_report(DatasetCounts{}, {r})["methods"]["landmarkboost"];
  EXPECT_TRUE(m["median_position_error_all_frames_m"].is_null());
  table = format_results_table(build_report(DatasetCounts{}, {r}));
  EXPECT_NE(table.find("landmarkboost              0.0000             -             -"), std::string::npos) << table;
}

// The generalization gap puts each method's held-out P@1 beside its P@1 and pose recall on each
// query session, from the report's own fields; without held-out observations the column is null
// and the table shows "-".
TEST(GeneralizationGap, SideBySideFromTheReportsSessions) {
  nlohmann::json report = build_report(DatasetCounts(), {sample_method("a"), sample_method("b")});
  MethodResult query = sample_method("a");  // P@1 0.5, pose recall 0.5
  nlohmann::json sessions = nlohmann::json::array();
  sessions.push_back({{"name", "query"}, {"methods", {{"a", session_method_report(query)}}}});
  sessions.push_back(
      {{"name", "night"}, {"methods", {{"a", {{"precision_at_1", 0.25}, {"pose_recall_20cm_5deg", 0.125}}}}}});
  report["sessions"] = sessions;
  EXPECT_EQ(session_method_report(query).at("precision_at_1").get<double>(), 0.5);
  EXPECT_EQ(session_method_report(query).at("frames_correct").get<int64_t>(), query.pose.num_correct);

  nlohmann::json gap = generalization_gap(report);
  EXPECT_TRUE(gap.at("precision_at_1").at("a").at("held_out_map_observations").is_null());
  EXPECT_EQ(gap.at("precision_at_1").at("a").at("sessions"), nlohmann::json({{"query", 0.5}, {"night", 0.25}}));
  EXPECT_EQ(gap.at("pose_recall_20cm_5deg").at("a").at("night").get<double>(), 0.125);
  EXPECT_TRUE(gap.at("precision_at_1").at("b").at("sessions").empty());  // in no session
  report["generalization_gap"] = gap;
  std::string table = format_generalization_gap(report);
  EXPECT_NE(table.find("pass --run"), std::string::npos) << table;
  EXPECT_NE(table.find("query P@1"), std::string::npos) << table;
  EXPECT_NE(table.find("night P@1"), std::string::npos) << table;
  EXPECT_NE(table.find("0.2500  0.1250"), std::string::npos) << table;

  report["held_out_map_observations"] = {
      {"frames", 3}, {"keypoints", 40}, {"methods", {{"a", {{"precision_at_1", 0.75}}}}}};
  gap = generalization_gap(report);
  EXPECT_EQ(gap.at("precision_at_1").at("a").at("held_out_map_observations").get<double>(), 0.75);
  report["generalization_gap"] = gap;
  table = format_generalization_gap(report);
  EXPECT_NE(table.find("(40 keypoints in 3 map frames"), std::string::npos) << table;
  EXPECT_NE(table.find("0.7500"), std::string::npos) << table;
  EXPECT_EQ(format_generalization_gap(nlohmann::json::object()), "");
}

TEST(BuildReport, RejectsBadMethods) {
  EXPECT_THROW(build_report({}, {sample_method("a"), sample_method("a")}), Error);
  EXPECT_THROW(build_report({}, {sample_method("")}), Error);
  MethodResult r = sample_method("x");
  r.frames.pop_back();
  EXPECT_THROW(build_report({}, {r}), Error);
}

}  // namespace
}  // namespace lmb
