// Fitting a method's walk calibration (infer/walk_confidence.h) on walks through the map's own
// calibration frames: the map sessions are walks, so their calibration frames in session order are
// walks whose every pose is known, and the "elsewhere" variant of a frame is the walk stepping into
// a place the map does not hold (a look-alike elsewhere, a frame from outside the map).
//
// Samples: for each calibration frame i of a session and each gap g = 1..max_gap, when the
// session's calibration frame i - g has a right "as is" pose (the last trusted pose of a walk that
// left frames i - g + 1 .. i - 1 unreported), every pose of frame i ("as is" and "elsewhere") with
// its walk evidence from that pose over g frames, labelled right or wrong against the truth; and
// when frame i - g's "elsewhere" pose is wrong and the frame rule reports it (a walk gone astray in
// a look-alike place), frame i's "elsewhere" pose with its evidence from that wrong pose. The
// scales are the median steps between consecutive right "as is" poses (floors 1 mm, 0.05 deg).
// The walk rule reports a pose beside the frame rule (WalkTracker), so its operating point is set on
// the samples the frame rule does not report: the higher of precision_threshold at
// target_precision over them and the smallest probability above which at most max_elsewhere_share
// of all "elsewhere" samples are added (a walk that leaves the map stops reporting). "passed"
// counts the samples either rule reports (the agreement test aside).
//
// Agreement: noise is the target_precision-quantile of the right "as is" poses' distance to their
// frames' map poses (position and rotation apart), step the same quantile of the motion between
// consecutive frames of the map sessions' truth; measured when there are at least min_poses right
// poses. The walk rule is not fitted (adds = false: it reports nothing) when there are fewer than
// min_poses samples or no sample is wrong (nothing to tell a jump from); the calibration is then
// the agreement alone. Not fitted at all (the frame rule judges every frame) when the frame
// calibration is not fitted or neither part can be.
//
// Deterministic: a function of the frame calibration's poses, the map's sessions and the options.
#pragma once

#include <cstdint>

#include <nlohmann/json.hpp>

#include "common/landmark_map.h"
#include "infer/walk_confidence.h"
#include "train/eval/pose_calibration_fit.h"

namespace lmb {

struct WalkCalibrationFit {
  bool fitted = false;
  WalkCalibration calibration;  // when fitted (threshold = the operating point)
  int64_t num_samples = 0;
  int64_t num_right = 0;
  int64_t num_elsewhere = 0;  // of the samples, "elsewhere" poses
  double precision_threshold = 0.0;
  double elsewhere_threshold = 0.0;
  int64_t passed = 0;
  int64_t passed_right = 0;
  int64_t elsewhere_passed = 0;
  nlohmann::json to_json() const;
};

// The walk samples of `frame_fit` (its poses and calibration) on `map` and the fit. max_gap in
// 1..1000. Throws lmb::Error on invalid options.
WalkCalibrationFit fit_walk_calibration_on_map(const LandmarkMap& map, const CalibrationFit& frame_fit,
                                               const PoseCalibrationOptions& options, int max_gap = 3);

}  // namespace lmb
