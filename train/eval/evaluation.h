// The evaluation of `lboost eval` (the paper's experiments) as a library: a model, the map it was
// trained on and its query frames -> every method's rankings, poses and metrics -> report.json
// (docs/report.md) and the results table. The CLI (train/cli/eval_command.cc) parses the flags
// into EvalOptions, calls run_evaluation and writes the files.
//
// Protocol. Query frames are the frames of the map's query sessions (every session of kind query,
// or those named by EvalOptions::query_sessions; outside sessions are never evaluated); metrics are
// reported over all of them and per session. A query keypoint's true landmark is its joint-mapping
// landmark when that landmark is one of the model's classes (the K landmarks the classifier was
// trained on), otherwise the keypoint is background for the metrics. The descriptor baselines
// search the same classes' observations in the map's non-query frames (all of the map sessions'
// observations, those training held out included). Each method (train/eval/methods.h) ranks at
// most top_k distinct landmarks per keypoint (without rejection) and accepts at most one match a
// keypoint (after its own rejection); every method's accepted matches go to the same pose stage
// (train/eval/pose_stage.h: P3P RANSAC with the same options and seed; no voting or clustering),
// then to the same RANSAC at each budget and seed of the sweep. Times are single-thread, one
// frame at a time (OpenCV and faiss limited to one thread): match = the method's timed matching,
// total = match + pose (the sweep is not timed).
//
// Held-out map observations (with EvalOptions::training_set): the class observations in map frames
// that the training run held out (never trained on). Every method ranks them in their own frames
// (the classifier sees the frame's other keypoints as context, as in training), the descriptor
// baselines searching the map observations without them; precision@1 and MRR over them stand
// beside each query session's in report["generalization_gap"].
//
// Pose confidence: each method's calibration is fitted on the map's own map-session frames, the
// same way for every method (train/eval/pose_calibration_fit.h; the descriptor baselines' index
// without those frames' observations), never on a query; report["methods"][M]["pose_confidence"]
// gives the precision and recall of "success" by the inlier rule and by the calibrated rule, the
// precision-recall curve over the calibrated probability, and both rules at every budget and seed
// of the sweep.
#pragma once

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "train/eval/methods.h"

namespace lmb {

struct EvalResult {
  nlohmann::json report;          // report.json without "training" (attach_training_summary)
  nlohmann::json keypoint_ranks;  // per method, per query frame, per keypoint: rank of the truth
  // What `lboost eval` prints: a heading ("Results on N query frames..."), the results table
  // (format_results_table) and the thread CPU time per frame of each method.
  std::string heading;
  std::string table;
  std::string cpu_line;
  // The generalization gap (format_generalization_gap): P@1 on the held-out map observations beside
  // P@1 and pose recall on each query session.
  std::string gap_table;
  // Precision and recall of "success" per method: the inlier rule and the calibrated rule
  // (format_confidence_table).
  std::string confidence_table;
};

// Runs every selected method on the query sessions' frames (and the held-out map observations).
// Throws lmb::Error on invalid options, a model of another map, an unknown, map or outside session
// named in query_sessions, no query frame, or no query keypoint of a model class.
EvalResult run_evaluation(const EvalOptions& options);

// The model and the map must describe the same landmarks (lboost eval and lboost localize): the
// same descriptor length, and every class's landmark is a landmark of the map at the model's
// position (within 1e-6 relative). Returns the landmark -> class flag. Throws lmb::Error naming
// both files ("<model>: class 3 (landmark 17) lies 2.5 m from that landmark in <map> (the model was
// trained on another map)").
std::vector<char> check_model_fits_map(const Model& model, const std::string& model_name, const LandmarkMap& map,
                                       const std::string& map_name);

// Copies RUN_DIR/summary.json (a finished `lboost train` run) into report["training"]. Throws
// lmb::Error when it is missing or not JSON.
void attach_training_summary(nlohmann::json& report, const std::filesystem::path& run_dir);

}  // namespace lmb
