// The results report of `lboost eval` (report.json, schema in DESIGN.md "The results report"),
// assembled from per-method metrics, plus the plain-text results table the CLI prints.
//
// Per method, besides DESIGN.md's fields, the report carries what jobs/plots.py draws:
//   "miss_rate_curve": {"n": [...], "fppi": [...], "miss_rate": [...]}
//   "pose_pr_curve":   {"threshold": [...], "recall": [...], "precision": [...]}
//   "per_frame":       {"localized": [0/1], "correct": [0/1], "position_error_m": [...],
//                       "rotation_error_deg": [...], "inlier_ratio": [...], "match_ms": [...],
//                       "total_ms": [...]}
//   "pose_recall_sweep": {"ransac_iterations": [...], "seeds": [...], "recall": [[per seed] per
//                        budget], "mean": [...], "min": [...], "max": [...]}
// and the extra scalars "log_average_miss_rate", "background_rejection_rate", "frames_localized",
// "frames_correct". Non-finite numbers (e.g. medians with no localized frame) are written as null.
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

// One evaluated method. frames: the outcomes given to evaluate_poses, for the per-frame timings
// (empty = per_frame has no match_ms / total_ms arrays).
struct MethodResult {
  std::string name;  // e.g. "landmarkboost", "bruteforce_hamming"
  RetrievalMetrics retrieval;
  PoseMetrics pose;
  PoseSweep sweep;                   // written as pose_recall_sweep when it has budgets
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

// Writes the report (2-space indent) via a temp file + rename. Throws lmb::Error on I/O failure.
void write_report(const std::filesystem::path& path, const nlohmann::json& report);

// A fixed-width table, one row per method: P@1, MRR, MR@FPPI=1, pose recall, AUC, median errors,
// inlier ratio, match and total ms per frame; then, when the report has pose_recall_sweep, the pose
// recall over the seeds (mean [min, max]) at each RANSAC budget.
std::string format_results_table(const nlohmann::json& report);

}  // namespace lmb
