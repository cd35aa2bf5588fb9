#include "train/eval/bundle_calibration_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "infer/bundle_localizer.h"
#include "infer/model.h"
#include "train/boost/training_set.h"
#include "train/eval/landmarkboost_matcher.h"
#include "train/eval/metrics.h"
#include "train/eval/pose_calibration_fit.h"
#include "train/eval/walk_calibration_fit.h"

namespace lmb {

namespace {

// The bundle's poses of `frames`, each localized in every area and once more "elsewhere" (in the
// areas that hold none of its view), with the areas' fusion without the frames' own exemplars.
std::vector<CalibrationPose> bundle_calibration_poses(const BundleCalibrationOptions& args,
                                                      const std::shared_ptr<AreaBundle>& bundle, const AreaFile& file,
                                                      const LandmarkMap& map, const std::vector<frame_t>& frames) {
  // The areas' descriptor fusion without the frames' own descriptors among its exemplars (else each
  // keypoint finds itself at distance 0), as `lboost export` fits a model's calibration.
  const std::vector<int64_t> own = calibration_frame_keypoints(map, frames);
  const auto rows = [](const Model& m) {
    return m.data().fusion.enabled() ? m.data().fusion.exemplar_begin.back() : int64_t{0};
  };
  std::vector<int64_t> file_rows(bundle->areas().size(), -1);  // per area: its file's exemplars (once loaded)
  bundle->set_model_transform([&](int32_t id, std::shared_ptr<const Model> model) {
    file_rows[static_cast<size_t>(id)] = rows(*model);
    return without_exemplars(model, map, own, /*keep_sole=*/true);
  });
  BundleLocalizerOptions lo;
  lo.localizer.classifier.use_inverted_file = args.inverted_file;
  lo.localizer.pose.seed = args.seed;
  lo.winner = AreaWinner::kSupport;
  const BundleLocalizer localizer(bundle, lo);
  const PoseThresholds thresholds;
  std::vector<CalibrationPose> poses;
  const auto started = std::chrono::steady_clock::now();
  auto last_line = started;
  for (size_t i = 0; i < frames.size(); ++i) {
    const MapFrame& frame = map.frames[frames[i]];
    const std::vector<Keypoint> keypoints(map.keypoints.begin() + frame.first_keypoint,
                                          map.keypoints.begin() + frame.first_keypoint + frame.num_keypoints);
    const std::vector<char> view = landmarks_in_view(map, frames[i]);
    std::vector<int32_t> all, away;
    for (const Area& area : file.split.areas) {
      all.push_back(area.id);
      const bool sees = std::any_of(area.landmarks.begin(), area.landmarks.end(), [&](landmark_t l) {
        return l >= 0 && static_cast<size_t>(l) < view.size() && view[static_cast<size_t>(l)] != 0;
      });
      if (!sees) away.push_back(area.id);
    }
    for (int variant = 0; variant < 2; ++variant) {
      const std::vector<int32_t>& ids = variant == 0 ? all : away;
      if (ids.empty()) continue;
      const BundleLocalizeResult r = localizer.localize_in(ids, map.cameras[frame.camera], keypoints,
                                                           map.descriptor(frame.first_keypoint), frame.gravity_in_cam);
      LMB_CHECK(r.errors.empty(), "bundle calibration: " << r.errors.front());
      if (r.area < 0) continue;
      CalibrationPose p;
      p.frame = frames[i];
      p.elsewhere = variant == 1;
      p.cam_from_world = r.result.pose.cam_from_world;
      p.evidence = r.evidence;
      p.right = pose_within(r.result.pose.cam_from_world, frame.cam_from_world, thresholds);
      poses.push_back(p);
    }
    const auto now = std::chrono::steady_clock::now();
    if (now - last_line >= std::chrono::seconds(30) || i + 1 == frames.size()) {
      last_line = now;
      const double elapsed = std::chrono::duration<double>(now - started).count();
      spdlog::info("bundle: calibration frame {} of {}, {:.0f} s, ETA {:.0f} s", i + 1, frames.size(), elapsed,
                   elapsed * static_cast<double>(frames.size() - i - 1) / static_cast<double>(i + 1));
    }
  }
  // The exemplars the calibration's models left out, counted on the models the bundle scored.
  int64_t exemplars = 0, left_out = 0;
  for (size_t id = 0; id < file_rows.size(); ++id) {
    if (file_rows[id] < 0) continue;
    exemplars += file_rows[id];
    left_out += file_rows[id] - rows(*bundle->model(static_cast<int32_t>(id)));
  }
  spdlog::info(
      "bundle: calibration poses of {} map frames, the areas' fusion without the frames' own {} of {} "
      "exemplars",
      frames.size(), left_out, exemplars);
  return poses;
}

}  // namespace

std::optional<BundleCalibration> fit_bundle_calibration(const BundleCalibrationOptions& args,
                                                        const std::shared_ptr<AreaBundle>& bundle, const AreaFile& file,
                                                        const LandmarkMap& map) {
  // The frames the areas' training held out (default training options), else every n-th map frame.
  PoseCalibrationOptions frame_options;
  frame_options.max_frames = args.max_frames;
  frame_options.target_precision = args.target_precision;
  TrainingSetOptions areas_training;  // the areas' training: default options, no fold models
  areas_training.calibration_folds = 0;
  frame_options = with_holdout_frames(frame_options, map, areas_training);
  const std::vector<frame_t> frames = calibration_frames(map, frame_options);
  std::vector<CalibrationPose> poses = bundle_calibration_poses(args, bundle, file, map, frames);
  const int64_t num_right = std::count_if(poses.begin(), poses.end(), [](const CalibrationPose& p) { return p.right; });
  const int64_t num_wrong = static_cast<int64_t>(poses.size()) - num_right;
  // A logistic needs both kinds; with right poses only, the calibration says it saw no wrong pose
  // (fit_calibration_on_poses: every pose reported, the walk's agreement still refuses one).
  const bool enough = num_right >= 5 && (num_wrong == 0 || num_wrong >= 5);
  const CalibrationFit fit =
      enough ? fit_calibration_on_poses(std::move(poses), static_cast<int64_t>(frames.size()), frame_options)
             : CalibrationFit{};
  if (!fit.fitted) {
    spdlog::warn(
        "bundle: no calibration: {} map frames gave {} right and {} wrong poses (at least 5 right, none or at least "
        "5 wrong, and {} in all are needed); the index is written without one",
        frames.size(), num_right, num_wrong, frame_options.min_poses);
    return std::nullopt;
  }
  spdlog::info(
      "bundle: calibration on {} map frames{}: {} poses ({} of them elsewhere), {} right; operating point {:.4f} "
      "(precision {}: {:.4f}; at most 1% of the frames elsewhere: {:.4f}) keeps {} poses, {} right, {} of them "
      "elsewhere",
      frames.size(),
      frame_options.frames.empty() ? " (the default training options hold none out)"
                                   : " (the ones the default training options hold out of training)",
      fit.num_poses, fit.num_elsewhere, fit.num_right, fit.calibration.threshold, args.target_precision,
      fit.precision_threshold, fit.elsewhere_threshold, fit.passed, fit.passed_right, fit.elsewhere_passed);
  if (!fit.saw_wrong_pose()) {
    spdlog::warn(
        "bundle: calibration: none of the {} poses is wrong, so nothing tells a wrong pose from a right one: every "
        "winning pose is reported (confidence 0.5); in tracking, the agreement of neighbouring frames' poses still "
        "refuses a pose",
        fit.num_poses);
  }
  BundleCalibration out;
  out.calibration = fit.calibration;
  // The walk calibration of track(): walks through the same frames in session order.
  const WalkCalibrationFit walk = fit_walk_calibration_on_map(map, fit, frame_options);
  if (walk.fitted) {
    out.walk = walk.calibration;
    const WalkCalibration& w = walk.calibration;
    spdlog::info(
        "bundle: walk calibration on {} walk samples ({} right, {} elsewhere): walk rule {} (operating point "
        "{:.4f}); agreement within {:.3f} m + g x {:.3f} m and {:.2f} deg + g x {:.2f} deg",
        walk.num_samples, walk.num_right, walk.num_elsewhere, w.adds ? "fitted" : "not fitted (no wrong sample)",
        w.threshold, std::sqrt(2.0) * w.agreement_noise_m, w.agreement_step_m, std::sqrt(2.0) * w.agreement_noise_deg,
        w.agreement_step_deg);
  } else {
    spdlog::warn(
        "bundle: no walk calibration (too few right poses to measure the agreement); track() judges "
        "each frame alone");
  }
  return out;
}

}  // namespace lmb
