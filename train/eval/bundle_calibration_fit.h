// The pose calibration of a bundle of area models (BundleLocalizeResult::evidence, fitted by
// `lboost bundle --map`), the bundle's counterpart of train/eval/pose_calibration_fit.h.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>

#include "common/landmark_map.h"
#include "infer/area_bundle.h"
#include "infer/pose_confidence.h"
#include "infer/walk_confidence.h"
#include "train/areas/area_file.h"

namespace lmb {

struct BundleCalibrationOptions {
  int max_frames = 100;        // map frames localized at most
  bool inverted_file = false;  // localize them with the inverted file
  uint64_t seed = 0;           // RANSAC seed
  double target_precision = 0.95;
};

struct BundleCalibration {
  PoseCalibration calibration;          // the operating point as its threshold
  std::optional<WalkCalibration> walk;  // the walk calibration of track(), when it could be fitted
};

// The bundle's pose calibration (infer/area_bundle.h, BundleLocalizeResult::evidence), fitted on
// the frames the areas' training held out (default training options; calibration_holdout_frames), else on
// map frames (train/eval/pose_calibration_fit.h, calibration_frames: every s-th frame of the map
// sessions) the way `lboost export` fits a model's (fit_calibration_on_poses), with the support
// rule and the areas' descriptor fusion without the frames' own exemplars; a pose is right within
// 0.2 m / 5 deg of the frame's map pose. Each frame twice: localized in every area (no prior: the
// most areas compete), and "elsewhere", in every area that holds no landmark in its view
// (landmarks_in_view), i.e. the frame as if taken where the map holds only look-alikes: a map
// frame's own areas rarely give a wrong pose, the elsewhere variant gives the wrong poses an
// aliased place gives. Operating point: the higher of the target precision's and the one that
// lets at most 1% of the frames' elsewhere variants pass. Then the walk calibration of
// BundleLocalizer::track on walks through the same frames (train/eval/walk_calibration_fit.h:
// the walk rule and the agreement of neighbouring poses, measured on the map). No query frame is
// read. When every pose is right the calibration says so (fit_calibration_on_poses: constant 0.5,
// operating point 0: every winning pose is reported) and the walk's agreement is what refuses a
// pose. Returns nothing (and logs why) with fewer than 5 right poses, 1 to 4 wrong ones, or fewer
// poses in all than PoseCalibrationOptions::min_poses (10).
std::optional<BundleCalibration> fit_bundle_calibration(const BundleCalibrationOptions& options,
                                                        const std::shared_ptr<AreaBundle>& bundle, const AreaFile& file,
                                                        const LandmarkMap& map);

}  // namespace lmb
