#include "train/eval/pose_calibration_fit.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

#include "common/error.h"
#include "train/boost/training_set.h"
#include "train/eval/pose_stage.h"

namespace lmb {

void PoseCalibrationOptions::check() const {
  LMB_CHECK(max_frames >= 1, "pose calibration: max_frames = " << max_frames << " must be >= 1");
  LMB_CHECK(target_precision > 0.0 && target_precision <= 1.0,
            "pose calibration: target_precision = " << target_precision << " must be in (0, 1]");
  LMB_CHECK(max_elsewhere_share >= 0.0 && max_elsewhere_share <= 1.0,
            "pose calibration: max_elsewhere_share = " << max_elsewhere_share << " must be in [0, 1]");
  LMB_CHECK(min_poses >= 1, "pose calibration: min_poses = " << min_poses << " must be >= 1");
}

std::vector<frame_t> calibration_frames(const LandmarkMap& map, int max_frames) {
  LMB_CHECK(max_frames >= 1, "pose calibration: max_frames = " << max_frames << " must be >= 1");
  const std::vector<frame_t> all = map.map_session_frames();
  // Every other frame at least, so that the frames between keep the descriptor baselines' index.
  const size_t step =
      std::max<size_t>(2, (all.size() + static_cast<size_t>(max_frames) - 1) / static_cast<size_t>(max_frames));
  std::vector<frame_t> out;
  for (size_t i = 0; i < all.size(); i += step) out.push_back(all[i]);
  return out;
}

PoseCalibrationOptions with_holdout_frames(PoseCalibrationOptions options, const LandmarkMap& map,
                                           const TrainingSetOptions& training) {
  if (cross_fitting_folds(map, training) > 0) {
    // Cross-fitted: every fold is held out of one fold model, so every map-session frame calibrates.
    options.frames = map.map_session_frames();
    std::sort(options.frames.begin(), options.frames.end());
  } else {
    options.frames = calibration_holdout_frames(map, training);
  }
  return options;
}

std::vector<frame_t> calibration_frames(const LandmarkMap& map, const PoseCalibrationOptions& options) {
  options.check();
  if (options.frames.empty()) return calibration_frames(map, options.max_frames);
  for (size_t i = 0; i < options.frames.size(); ++i) {
    const frame_t f = options.frames[i];
    LMB_CHECK(f >= 0 && f < map.num_frames() && !map.frames[f].is_query,
              "pose calibration: frame " << f << " is not a map frame of the map");
    LMB_CHECK(i == 0 || f > options.frames[i - 1], "pose calibration: the frames must be ascending and distinct");
  }
  return options.frames;
}

double pass_share_threshold(std::vector<double> probability, int64_t num_frames, double max_share) {
  LMB_CHECK(num_frames >= static_cast<int64_t>(probability.size()),
            "pose calibration: " << probability.size() << " probabilities for " << num_frames << " frames");
  LMB_CHECK(max_share >= 0.0 && max_share <= 1.0, "pose calibration: share " << max_share << " is outside [0, 1]");
  // At most `allowed` may pass (the rounding tolerates the share's binary representation).
  const auto allowed = static_cast<size_t>(std::floor(max_share * static_cast<double>(num_frames) + 1e-9));
  if (probability.size() <= allowed) return 0.0;
  std::sort(probability.begin(), probability.end(), std::greater<>());
  // Above the (allowed + 1)-th highest: it and every probability equal to it fail.
  return std::nextafter(probability[allowed], std::numeric_limits<double>::infinity());
}

std::vector<char> landmarks_in_view(const LandmarkMap& map, frame_t f) {
  LMB_CHECK(f >= 0 && f < map.num_frames(), "pose calibration: frame " << f << " is not in the map");
  const MapFrame& frame = map.frames[f];
  const Camera& camera = map.cameras[frame.camera];
  std::vector<char> view(map.landmarks.size(), 0);
  for (size_t l = 0; l < map.landmarks.size(); ++l) {
    Eigen::Vector2d pixel;
    if (!camera.project(frame.cam_from_world * map.landmarks[l].position, &pixel)) continue;
    view[l] = pixel.x() >= 0 && pixel.y() >= 0 && pixel.x() < camera.width && pixel.y() < camera.height;
  }
  for (int64_t k = frame.first_keypoint; k < frame.first_keypoint + frame.num_keypoints; ++k) {
    const landmark_t l = map.keypoint_landmark[k];
    if (l >= 0 && static_cast<size_t>(l) < view.size()) view[l] = 1;
  }
  return view;
}

std::vector<int64_t> calibration_frame_keypoints(const LandmarkMap& map, const std::vector<frame_t>& frames) {
  std::vector<int64_t> out;
  for (frame_t f : frames) {
    const MapFrame& frame = map.frames[f];
    for (int64_t k = frame.first_keypoint; k < frame.first_keypoint + frame.num_keypoints; ++k) out.push_back(k);
  }
  std::sort(out.begin(), out.end());
  return out;
}

EvalQuery map_frame_query(const LandmarkMap& map, frame_t f) {
  const MapFrame& frame = map.frames[f];
  EvalQuery q;
  q.frame = f;
  q.camera = &map.cameras[frame.camera];
  q.keypoints.assign(map.keypoints.begin() + frame.first_keypoint,
                     map.keypoints.begin() + frame.first_keypoint + frame.num_keypoints);
  q.descriptors = map.descriptor(frame.first_keypoint);
  q.gravity_in_cam = frame.gravity_in_cam;
  q.true_cam_from_world = frame.cam_from_world;
  q.truth.assign(q.keypoints.size(), kInvalidLandmarkId);
  return q;
}

nlohmann::json CalibrationFit::to_json() const {
  nlohmann::json j = {{"fitted", fitted},
                      {"frames_source", frames_source},
                      {"frames", num_frames},
                      {"poses", num_poses},
                      {"poses_right", num_right},
                      {"poses_elsewhere", num_elsewhere},
                      {"poses_passed", passed},
                      {"poses_elsewhere_passed", elsewhere_passed},
                      {"poses_passed_right", passed_right}};
  if (fitted) {
    j["saw_wrong_pose"] = saw_wrong_pose();
    nlohmann::json weights = nlohmann::json::object();
    for (int k = 0; k < PoseEvidence::kNumFeatures; ++k) {
      weights[PoseEvidence::feature_names()[k]] = calibration.weights[k];
    }
    j["weights"] = weights;
    j["bias"] = calibration.bias;
    j["threshold"] = calibration.threshold;
    j["precision_threshold"] = precision_threshold;
    j["elsewhere_threshold"] = elsewhere_threshold;
    j["target_precision"] = calibration.target_precision;
  }
  return j;
}

std::vector<CalibrationPose> calibration_poses(const Matcher& matcher, const LandmarkMap& map,
                                               const std::vector<frame_t>& frames, const PoseEstimatorOptions& pose,
                                               int max_correspondences, const PoseThresholds& thresholds) {
  pose.check();
  thresholds.check();
  std::vector<CalibrationPose> poses;
  for (frame_t f : frames) {
    const EvalQuery q = map_frame_query(map, f);
    const FrameMatches m = matcher.match(q);
    // "Elsewhere": the frame matched as if no landmark in its view were in the map.
    const std::vector<char> view = landmarks_in_view(map, f);
    const std::vector<Correspondence> elsewhere = matcher.accepted_without(
        q, [&](landmark_t l) { return l >= 0 && static_cast<size_t>(l) < view.size() && view[l] != 0; });
    for (int variant = 0; variant < 2; ++variant) {
      const std::vector<Correspondence>& accepted = variant == 0 ? m.accepted : elsewhere;
      const PoseInput input = select_correspondences(q, accepted, max_correspondences);
      const PoseResult r = estimate_absolute_pose(*q.camera, input.pixels, input.points_world, pose, input.quality);
      if (!r.success) continue;
      const PoseEvidence evidence =
          pose_evidence(*q.camera, input.pixels, input.quality, r, static_cast<int>(q.keypoints.size()));
      const bool right = pose_within(r.cam_from_world, q.true_cam_from_world, thresholds);
      poses.push_back(CalibrationPose{f, variant == 1, r.cam_from_world, evidence, right});
    }
  }
  return poses;
}

CalibrationFit fit_calibration_on_poses(std::vector<CalibrationPose> poses, int64_t num_frames,
                                        const PoseCalibrationOptions& options) {
  options.check();
  CalibrationFit fit;
  fit.num_frames = num_frames;
  fit.poses = std::move(poses);
  std::vector<PoseEvidence> evidence;
  std::vector<char> right;
  for (const CalibrationPose& c : fit.poses) {
    evidence.push_back(c.evidence);
    right.push_back(c.right ? 1 : 0);
    fit.num_elsewhere += c.elsewhere ? 1 : 0;
  }
  fit.num_poses = static_cast<int64_t>(evidence.size());
  fit.num_right = std::count(right.begin(), right.end(), 1);
  if (fit.num_poses < options.min_poses) return fit;
  if (!fit.saw_wrong_pose()) {
    // Nothing tells a wrong pose from a right one: a logistic fitted on one label is a constant
    // near 1 whatever the evidence. Say so instead: every pose is 0.5 and reported.
    fit.calibration = PoseCalibration{};
    fit.calibration.threshold = 0.0;
    fit.calibration.num_samples = fit.num_poses;
    fit.calibration.num_positive = fit.num_right;
    fit.calibration.target_precision = options.target_precision;
    fit.passed = fit.passed_right = fit.num_poses;
    fit.elsewhere_passed = fit.num_elsewhere;
    fit.fitted = true;
    return fit;
  }
  fit.calibration = fit_pose_calibration(evidence, right);
  std::vector<double> p;
  for (const PoseEvidence& e : evidence) p.push_back(fit.calibration.probability(e));
  fit.precision_threshold = precision_threshold(p, right, options.target_precision);
  std::vector<double> p_elsewhere;
  for (size_t i = 0; i < p.size(); ++i) {
    if (fit.poses[i].elsewhere) p_elsewhere.push_back(p[i]);
  }
  fit.elsewhere_threshold = pass_share_threshold(p_elsewhere, fit.num_frames, options.max_elsewhere_share);
  fit.calibration.threshold = std::max(fit.precision_threshold, fit.elsewhere_threshold);
  fit.calibration.target_precision = options.target_precision;
  fit.calibration.check("pose calibration");
  for (size_t i = 0; i < p.size(); ++i) {
    if (p[i] < fit.calibration.threshold) continue;
    ++fit.passed;
    fit.passed_right += right[i];
    fit.elsewhere_passed += fit.poses[i].elsewhere ? 1 : 0;
  }
  fit.fitted = true;
  return fit;
}

CalibrationFit fit_method_calibration(const Matcher& matcher, const LandmarkMap& map, const PoseEstimatorOptions& pose,
                                      int max_correspondences, const PoseThresholds& thresholds,
                                      const PoseCalibrationOptions& options) {
  const std::vector<frame_t> frames = calibration_frames(map, options);
  LMB_CHECK(!frames.empty(), "pose calibration: the map has no frame of a map session to calibrate on");
  CalibrationFit fit =
      fit_calibration_on_poses(calibration_poses(matcher, map, frames, pose, max_correspondences, thresholds),
                               static_cast<int64_t>(frames.size()), options);
  fit.frames_source = options.frames.empty() ? "trained" : "held_out";
  return fit;
}

CalibrationFit fit_cross_fitted_calibration(const std::vector<CalibrationFold>& folds, const LandmarkMap& map,
                                            const PoseEstimatorOptions& pose, int max_correspondences,
                                            const PoseThresholds& thresholds, const PoseCalibrationOptions& options) {
  LMB_CHECK(!folds.empty(), "pose calibration: no calibration fold");
  std::vector<CalibrationPose> poses;
  int64_t num_frames = 0;
  for (const CalibrationFold& fold : folds) {
    LMB_CHECK(fold.matcher != nullptr && !fold.frames.empty(), "pose calibration: a fold without matcher or frames");
    std::vector<CalibrationPose> p =
        calibration_poses(*fold.matcher, map, fold.frames, pose, max_correspondences, thresholds);
    poses.insert(poses.end(), p.begin(), p.end());
    num_frames += static_cast<int64_t>(fold.frames.size());
  }
  // In frame order, as calibration_poses gives them for one matcher (the walk calibration reads them so).
  std::stable_sort(poses.begin(), poses.end(),
                   [](const CalibrationPose& a, const CalibrationPose& b) { return a.frame < b.frame; });
  CalibrationFit fit = fit_calibration_on_poses(std::move(poses), num_frames, options);
  fit.frames_source = "cross_fitted";
  return fit;
}

}  // namespace lmb
