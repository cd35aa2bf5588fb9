// The results report of `lboost eval` (report.json, every field documented in docs/report.md),
// assembled from per-method metrics, plus the plain-text results tables the CLI prints. Non-finite
// numbers (e.g. medians with no localized frame) are written as null; non-finite settings and the
// medians over all query frames (infinite when half of the frames have no pose) as strings
// (json_number_or_string).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "train/eval/metrics.h"

namespace lmb {

struct DatasetCounts {
  int64_t map_frames = 0;
  int64_t query_frames = 0;
  int64_t landmarks = 0;
  int64_t query_keypoints = 0;
  int64_t query_keypoints_with_truth = 0;
};

// Pose recall at one pair of thresholds.
struct ThresholdRecall {
  PoseThresholds thresholds;
  int64_t frames_correct = 0;
  double recall = 0.0;
};

// One evaluated method. frames: the outcomes given to evaluate_poses, for the per-frame timings
// (empty = per_frame has no match_ms / total_ms arrays). recall_at_thresholds and sweep are
// written when not empty.
struct MethodResult {
  std::string name;  // e.g. "landmarkboost", "bruteforce_hamming"
  RetrievalMetrics retrieval;
  MatchMetrics matches;
  PoseMetrics pose;  // at the primary thresholds
  std::vector<ThresholdRecall> recall_at_thresholds;
  PoseSweep sweep;
  std::vector<FrameOutcome> frames;  // same order as pose's per-frame vectors; may be empty
};

// A finite number as a JSON number; a non-finite one as the string "inf", "-inf" or "nan" (JSON has
// no such numbers), for the report's settings.
nlohmann::json json_number_or_string(double value);

// The report object for one method.
nlohmann::json method_report(const MethodResult& result);

// The whole report. Throws lmb::Error on an empty or repeated method name, or when a method's
// frames are neither empty nor as many as its pose metrics' frames.
nlohmann::json build_report(const DatasetCounts& dataset, const std::vector<MethodResult>& methods);

// One query session's share of a method's run (report["sessions"][i]["methods"][name]):
// precision_at_1, mrr, pose_recall_20cm_5deg, frames_localized, frames_correct and, when the
// result has a sweep, pose_recall_sweep {ransac_iterations, mean, min, max}.
nlohmann::json session_method_report(const MethodResult& result);

// report["generalization_gap"] from the report's "sessions" and "held_out_map_observations":
//   {"precision_at_1": {METHOD: {"held_out_map_observations": p or null, "sessions": {NAME: p}}},
//    "pose_recall_20cm_5deg": {METHOD: {NAME: r}}}
// (null where the report has no held-out observations: eval without --run).
nlohmann::json generalization_gap(const nlohmann::json& report);

// Writes the report (2-space indent) via a temp file + rename. Throws lmb::Error on I/O failure.
void write_report(const std::filesystem::path& path, const nlohmann::json& report);

// A fixed-width table, one row per method: P@1, MRR, MR@FPPI=1, match precision and recall,
// background rejection, pose recall, AUC, median errors, inlier ratio, match and total ms per
// frame; then the 7-Scenes convention (pose recall at 5 cm / 5 deg, median errors over all query
// frames); then, when --pose-thresholds is not just the default pair, the pose recall at each pair;
// then, when the report has pose_recall_sweep, the pose recall over the seeds (mean [min, max]) at
// each RANSAC budget. docs/report.md explains every column.
std::string format_results_table(const nlohmann::json& report);

// The generalization gap as a table, one row per method: P@1 on the held-out map observations ("-"
// without them), then P@1 and pose recall on each query session. Empty when the report has no
// "generalization_gap".
std::string format_generalization_gap(const nlohmann::json& report);

// Precision and recall of "success" per method, from report["methods"][M]["pose_confidence"]: the
// inlier rule (>= min_inliers inliers) and the calibrated rule (its probability at least the
// operating point) at the primary RANSAC budget and seed, then the mean [min, max] over the
// sweep's seeds at that budget when the sweep has it. Empty when no method has pose_confidence.
std::string format_confidence_table(const nlohmann::json& report);

}  // namespace lmb
