#include "train/eval/bundle_calibration_fit.h"

#include <algorithm>
#include <chrono>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "infer/bundle_localizer.h"
#include "infer/model.h"
#include "train/boost/training_set.h"
#include "train/eval/landmarkboost_matcher.h"
#include "train/eval/metrics.h"
#include "train/eval/pose_calibration_fit.h"

namespace lmb {

bool fit_bundle_calibration(const BundleCalibrationOptions& args, const std::shared_ptr<AreaBundle>& bundle,
                            const AreaFile& file, const LandmarkMap& map, PoseCalibration* out) {
  // The frames the areas' training held out (default training options), else every n-th map frame.
  PoseCalibrationOptions frame_options;
  frame_options.max_frames = args.max_frames;
  TrainingSetOptions areas_training;  // the areas' training: default options, no fold models
  areas_training.calibration_folds = 0;
  frame_options = with_holdout_frames(frame_options, map, areas_training);
  const std::vector<frame_t> frames = calibration_frames(map, frame_options);
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
  std::vector<PoseEvidence> evidence;
  std::vector<char> right, elsewhere;
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
      evidence.push_back(r.evidence);
      right.push_back(pose_within(r.result.pose.cam_from_world, frame.cam_from_world, thresholds) ? 1 : 0);
      elsewhere.push_back(static_cast<char>(variant));
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
  const int64_t num_right = std::count(right.begin(), right.end(), 1);
  const int64_t num_wrong = static_cast<int64_t>(right.size()) - num_right;
  if (num_right < 5 || num_wrong < 5) {
    spdlog::warn(
        "bundle: no calibration: {} map frames gave {} poses, {} right and {} wrong (at least 5 of each "
        "are needed); the index is written without one",
        frames.size(), right.size(), num_right, num_wrong);
    return false;
  }
  PoseCalibration c = fit_pose_calibration(evidence, right);
  std::vector<double> p;
  for (const PoseEvidence& e : evidence) p.push_back(c.probability(e));
  const double for_precision = precision_threshold(p, right, args.target_precision);
  std::vector<double> p_elsewhere;
  for (size_t i = 0; i < p.size(); ++i) {
    if (elsewhere[i]) p_elsewhere.push_back(p[i]);
  }
  const double for_elsewhere = pass_share_threshold(p_elsewhere, static_cast<int64_t>(frames.size()), 0.01);
  c.threshold = std::max(for_precision, for_elsewhere);
  c.target_precision = args.target_precision;
  c.check("bundle calibration");
  int64_t kept = 0, kept_right = 0, kept_elsewhere = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    kept += p[i] >= c.threshold;
    kept_right += p[i] >= c.threshold && right[i];
    kept_elsewhere += p[i] >= c.threshold && elsewhere[i];
  }
  spdlog::info(
      "bundle: calibration on {} map frames{}: {} poses ({} of them elsewhere), {} right; the areas' fusion "
      "without the frames' own {} of {} exemplars; operating point {:.4f} (precision {}: {:.4f}; at most 1% of the "
      "frames elsewhere: {:.4f}) keeps {} poses, {} right, {} of them elsewhere",
      frames.size(),
      frame_options.frames.empty() ? " (the default training options hold none out)"
                                   : " (the ones the default training options hold out of training)",
      right.size(), p_elsewhere.size(), num_right, left_out, exemplars, c.threshold, args.target_precision,
      for_precision, for_elsewhere, kept, kept_right, kept_elsewhere);
  *out = c;
  return true;
}

}  // namespace lmb
