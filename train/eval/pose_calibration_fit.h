// Fitting a method's pose calibration (infer/pose_confidence.h) where the truth is known and no
// query session is involved: on frames of the map's own map sessions, whose poses the map holds.
// `lboost export` fits LandmarkBoost's and stores it in model.lbm; `lboost eval` fits every
// method's the same way (each with its own matcher) before it evaluates the queries.
//
// The calibration poses. Calibration frames: every s-th frame of the map sessions (map order,
// s = max(2, ceil(map frames / max_frames)): the frames between keep the baselines' index). Each frame is matched by
// the method, and two poses are estimated with the evaluation's pose stage (train/eval/pose_stage.h, same options and
// seed):
//   - "as is": the frame's accepted matches;
//   - "elsewhere": the frame matched as if no landmark in its view (landmarks_in_view) were in the
//     map (Matcher::accepted_without: each keypoint's best remaining landmark under the method's
//     own rejection), i.e. the frame as if taken in a place the map does not hold: what it matches
//     are the aliased landmarks (a door, a poster of another place), which is how a wrong pose
//     with many inliers arises in an aliased building and how a query from outside the map looks.
//     (Dropping the frame's own matches instead leaves only the keypoints that matched elsewhere
//     anyway and misses the ones whose next-best landmark is an alias.)
// A pose enters the fit when the estimator reports success (at least min_inliers inliers): the
// calibration decides among the poses the inlier rule would report. Label: within the pose
// thresholds of the frame's map pose. Features: PoseEvidence, the same for every method.
// The operating point is the higher of precision_threshold at target_precision over the fitted
// poses and the smallest probability above which at most max_elsewhere_share of the calibration
// frames' "elsewhere" variants pass.
//
// Honesty: no query frame is read. The map frames are frames the methods have seen (LandmarkBoost
// trained on their observations, except the held-out ones; the descriptor baselines are given
// their index without the calibration frames' observations, MethodContext::excluded_keypoints), so
// their poses are easier than a query's; the "elsewhere" poses supply the wrong poses a map frame
// rarely yields. Deterministic: a function of the map, the matcher, the options and the seed.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/landmark_map.h"
#include "infer/pose_confidence.h"
#include "infer/pose_estimator.h"
#include "train/boost/boost_options.h"
#include "train/eval/matcher.h"
#include "train/eval/metrics.h"

namespace lmb {

struct PoseCalibrationOptions {
  int max_frames = 200;            // calibration frames at most, >= 1
  double target_precision = 0.95;  // the operating point's precision on the fitted poses, (0, 1]
  // The operating point also lets at most this share of the calibration frames' "elsewhere"
  // variants (the frame where no landmark of its view is in the map) pass, in [0, 1]: the share of
  // frames from outside the map reported localized. 1 = no such bound.
  double max_elsewhere_share = 0.01;
  int min_poses = 10;  // fewer fitted poses: no calibration (CalibrationFit::fitted false)
  // Non-empty: the calibration frames are exactly these map-session frames (ascending; the frames
  // the model's training held out, calibration_holdout_frames), and max_frames is not used.
  std::vector<frame_t> frames;
  void check() const;  // throws lmb::Error naming the field
};

// The calibration options of a model trained with `training` (its run's training-set options, or
// the defaults) on `map`: `options` with the frames its training held out
// (calibration_holdout_frames), every map-session frame when cross-fitted (cross_fitting_folds),
// or `options` as given when it held out none.
PoseCalibrationOptions with_holdout_frames(PoseCalibrationOptions options, const LandmarkMap& map,
                                           const TrainingSetOptions& training);
// The calibration frames of `options` on `map`: options.frames, or calibration_frames(max_frames).
std::vector<frame_t> calibration_frames(const LandmarkMap& map, const PoseCalibrationOptions& options);

// The calibration frames of `map` (see the file comment), ascending.
std::vector<frame_t> calibration_frames(const LandmarkMap& map, int max_frames);
// The smallest threshold at which at most floor(max_share * num_frames) of `probability` (one per
// frame at most, num_frames >= its size) are >= it: 0 when that many or fewer are given, else
// just above the (allowed + 1)-th highest. Throws lmb::Error on invalid sizes or share.
double pass_share_threshold(std::vector<double> probability, int64_t num_frames, double max_share);
// Per landmark of the map, whether it is in view of frame f: one of the frame's keypoints observes
// it, or its position projects into the image at the frame's map pose (in front of the camera;
// occlusion is not modelled). Throws lmb::Error for a frame outside the map.
std::vector<char> landmarks_in_view(const LandmarkMap& map, frame_t f);
// Their map keypoints, ascending (what the descriptor baselines leave out of their index).
std::vector<int64_t> calibration_frame_keypoints(const LandmarkMap& map, const std::vector<frame_t>& frames);

// One pose the calibration was fitted on (the estimator's success), in frame order, the frame's
// "as is" pose before its "elsewhere" one.
struct CalibrationPose {
  frame_t frame = -1;
  bool elsewhere = false;
  Rigid3d cam_from_world;
  PoseEvidence evidence;
  bool right = false;
};

struct CalibrationFit {
  bool fitted = false;                 // false: too few poses (num_poses < min_poses)
  PoseCalibration calibration;         // when fitted (threshold = the operating point)
  int64_t num_frames = 0;              // calibration frames
  int64_t num_poses = 0;               // poses fitted on (both variants)
  int64_t num_right = 0;               // of them right
  int64_t num_elsewhere = 0;           // of the poses, "elsewhere" ones
  double precision_threshold = 0.0;    // the operating point for target_precision alone
  double elsewhere_threshold = 0.0;    // ... for max_elsewhere_share alone
  int64_t elsewhere_passed = 0;        // "elsewhere" poses at or above the operating point
  int64_t passed = 0;                  // poses at or above the operating point
  int64_t passed_right = 0;            // of them right
  std::vector<CalibrationPose> poses;  // the poses fitted on (what the walk calibration reads)
  // Whether a fitted pose is wrong. When none is, the calibration cannot tell a wrong pose from a
  // right one: it is the constant 0.5 with operating point 0 (every pose the inlier rule finds is
  // reported), and the walks' agreement (walk_calibration_fit.h) is what still refuses a pose.
  bool saw_wrong_pose() const { return num_right < num_poses; }
  // Which frames: "cross_fitted" (each fold by the fold model without it), "held_out" (frames
  // the model's training held out) or "trained" (frames it trained on: a small map without folds).
  std::string frames_source = "trained";
  nlohmann::json to_json() const;
};

// The poses of `frames` matched by `matcher`, both variants each, with `pose` (at most
// max_correspondences correspondences, 0 = all), in frame order (see the file comment).
std::vector<CalibrationPose> calibration_poses(const Matcher& matcher, const LandmarkMap& map,
                                               const std::vector<frame_t>& frames, const PoseEstimatorOptions& pose,
                                               int max_correspondences, const PoseThresholds& thresholds);
// The calibration fitted on `poses` of num_frames frames (the logistic, then the operating point).
CalibrationFit fit_calibration_on_poses(std::vector<CalibrationPose> poses, int64_t num_frames,
                                        const PoseCalibrationOptions& options);

// Matches every calibration frame with `matcher`, estimates both poses and fits the calibration.
// Throws lmb::Error on invalid options or a map without map-session frames.
CalibrationFit fit_method_calibration(const Matcher& matcher, const LandmarkMap& map, const PoseEstimatorOptions& pose,
                                      int max_correspondences, const PoseThresholds& thresholds,
                                      const PoseCalibrationOptions& options);

// Cross-fitting (training_set.calibration_folds): each fold of the frames matched by the method as
// it is without that fold (LandmarkBoost: the fold model trained without it; the descriptor
// baselines: an index without its observations). The poses of every fold are pooled, in frame
// order, and one calibration is fitted on them; it applies to the model trained on every frame.
struct CalibrationFold {
  const Matcher* matcher = nullptr;
  std::vector<frame_t> frames;  // ascending, never seen by `matcher`
};
CalibrationFit fit_cross_fitted_calibration(const std::vector<CalibrationFold>& folds, const LandmarkMap& map,
                                            const PoseEstimatorOptions& pose, int max_correspondences,
                                            const PoseThresholds& thresholds, const PoseCalibrationOptions& options);

// One map frame as a query, its truth every keypoint kInvalidLandmarkId (the calibration needs the
// frame's pose only; evaluation's frame_query fills the truth in).
EvalQuery map_frame_query(const LandmarkMap& map, frame_t f);

}  // namespace lmb
