// Walks in `lboost eval`: each query session is a walk (its frames in map order) that a method
// localizes frame after frame, every frame's pose judged by WalkTracker (infer/walk_confidence.h):
// the walk rule (the method's walk calibration, train/eval/walk_calibration_fit.h) while a trusted
// pose is at most max_gap frames back, the frame rule (its pose calibration) otherwise. The same
// frames' poses are judged by the frame rule alone beside it, so the report says what the walk adds.
//
// Per walk and RANSAC seed: frames, frames right (a pose within the thresholds, as the inlier rule
// reports it), frames reported (localized by the rule), of them right, precision and recall, the
// mean and 95th-percentile time a frame (the method's match + pose time: a walk relocalizes with the
// same work), the first reported frame and the time until it. With outside frames (a second place
// the map does not hold), each walk continues into them as a walk leaving the map: how many of them
// are reported, and how many after the first two.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "infer/walk_confidence.h"
#include "train/eval/metrics.h"
#include "train/eval/pose_calibration_fit.h"
#include "train/eval/walk_calibration_fit.h"

namespace lmb {

struct WalkInput {
  std::string name;                                // the session's name
  std::vector<std::vector<FrameOutcome>> by_seed;  // [seed][frame in walk order]
};

// The walks' report for one method: "calibration" (walk_fit.to_json()), "seeds", per walk
// "walks" (per seed the figures above for the walk rule and the frame rule), and "total" (summed
// over the walks, per seed). `outside_by_seed` ([seed][frame]) may
// be empty. Throws lmb::Error when the frame calibration is not fitted or the seed counts differ.
nlohmann::json evaluate_walks(const std::vector<WalkInput>& walks,
                              const std::vector<std::vector<FrameOutcome>>& outside_by_seed,
                              const CalibrationFit& frame_fit, const WalkCalibrationFit& walk_fit,
                              const std::vector<uint64_t>& seeds, const PoseThresholds& thresholds);

// Per rule ("walk_rule", "frame_rule") and figure of `walk` (evaluate_walks' report), its mean, min
// and max over the seeds' totals.
nlohmann::json walk_summary(const nlohmann::json& walk);

// The text table of every method's walk totals in `report` (methods.M.pose_confidence.walk); empty
// when none has one.
std::string format_walk_table(const nlohmann::json& report);

}  // namespace lmb
