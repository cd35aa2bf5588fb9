// The evaluation of `lboost eval` (the paper's experiments) as a library: a model, the map it was
// trained on and its query frames -> every method's rankings, poses and metrics -> report.json
// (docs/report.md) and the results table. The CLI (train/cli/eval_command.cc) parses the flags
// into EvalOptions, calls run_evaluation and writes the files.
//
// Protocol. Query frames are the map's frames marked is_query; a query keypoint's true landmark
// is its joint-mapping landmark when that landmark is one of the model's classes (the K landmarks
// the classifier was trained on), otherwise the keypoint is background for the metrics. The
// descriptor baselines search the same classes' observations in the map's non-query frames (the
// observations training used). Each method (train/eval/methods.h) ranks at most top_k distinct
// landmarks per keypoint (without rejection) and accepts at most one match a keypoint (after its
// own rejection); every method's accepted matches go to the same pose stage
// (train/eval/pose_stage.h: P3P RANSAC with the same options and seed; no voting or clustering),
// then to the same RANSAC at each budget and seed of the sweep. Times are single-thread, one
// frame at a time (OpenCV and faiss limited to one thread): match = the method's timed matching,
// total = match + pose (the sweep is not timed).
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
};

// Runs every selected method on the map's query frames. Throws lmb::Error on invalid options, a
// model of another map, a map without query frames or without query keypoints of a model class.
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
