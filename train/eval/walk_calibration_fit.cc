#include "train/eval/walk_calibration_fit.h"

#include <algorithm>
#include <map>

#include "common/error.h"
#include "common/stats.h"

namespace lmb {

namespace {

// Per session, its calibration frames in order, each with its "as is" and "elsewhere" poses.
struct WalkFrame {
  const CalibrationPose* as_is = nullptr;
  const CalibrationPose* elsewhere = nullptr;
};

std::vector<std::vector<WalkFrame>> calibration_walks(const LandmarkMap& map, const CalibrationFit& fit,
                                                      const PoseCalibrationOptions& options) {
  std::map<frame_t, WalkFrame> by_frame;
  for (const CalibrationPose& p : fit.poses) {
    WalkFrame& w = by_frame[p.frame];
    (p.elsewhere ? w.elsewhere : w.as_is) = &p;
  }
  // Every calibration frame holds its place in its session's walk, with or without a pose (a frame
  // without one is a frame the walk leaves unreported).
  std::map<int32_t, std::vector<WalkFrame>> walks;
  for (frame_t f : calibration_frames(map, options)) {
    const auto it = by_frame.find(f);
    walks[map.frames[f].session].push_back(it == by_frame.end() ? WalkFrame{} : it->second);
  }
  std::vector<std::vector<WalkFrame>> out;
  for (auto& [session, w] : walks) out.push_back(std::move(w));
  return out;
}

}  // namespace

nlohmann::json WalkCalibrationFit::to_json() const {
  nlohmann::json j = {{"fitted", fitted},
                      {"samples", num_samples},
                      {"samples_right", num_right},
                      {"samples_elsewhere", num_elsewhere},
                      {"samples_passed", passed},
                      {"samples_passed_right", passed_right},
                      {"samples_elsewhere_passed", elsewhere_passed}};
  if (fitted) {
    nlohmann::json weights = nlohmann::json::object();
    for (int k = 0; k < WalkEvidence::kNumFeatures; ++k) {
      weights[WalkEvidence::feature_names()[k]] = calibration.weights[k];
    }
    j["weights"] = weights;
    j["bias"] = calibration.bias;
    j["threshold"] = calibration.threshold;
    j["precision_threshold"] = precision_threshold;
    j["elsewhere_threshold"] = elsewhere_threshold;
    j["translation_scale_m"] = calibration.translation_scale_m;
    j["rotation_scale_deg"] = calibration.rotation_scale_deg;
    j["max_gap"] = calibration.max_gap;
    j["target_precision"] = calibration.target_precision;
  }
  return j;
}

WalkCalibrationFit fit_walk_calibration_on_map(const LandmarkMap& map, const CalibrationFit& frame_fit,
                                               const PoseCalibrationOptions& options, int max_gap) {
  options.check();
  LMB_CHECK(max_gap >= 1 && max_gap <= 1000, "walk calibration: max_gap = " << max_gap << " must be in 1..1000");
  WalkCalibrationFit fit;
  if (!frame_fit.fitted) return fit;
  const PoseCalibration& frame = frame_fit.calibration;
  const std::vector<std::vector<WalkFrame>> walks = calibration_walks(map, frame_fit, options);
  // The scales: the median step between consecutive right "as is" poses.
  std::vector<double> steps_m, steps_deg;
  for (const auto& walk : walks) {
    for (size_t i = 1; i < walk.size(); ++i) {
      const CalibrationPose* a = walk[i - 1].as_is;
      const CalibrationPose* b = walk[i].as_is;
      if (a == nullptr || b == nullptr || !a->right || !b->right) continue;
      steps_m.push_back(position_error(a->cam_from_world, b->cam_from_world));
      steps_deg.push_back(rotation_error_deg(a->cam_from_world, b->cam_from_world));
    }
  }
  if (steps_m.empty()) return fit;
  WalkCalibration scales;
  scales.translation_scale_m = std::max(1e-3, median(steps_m));
  scales.rotation_scale_deg = std::max(0.05, median(steps_deg));
  scales.max_gap = max_gap;

  std::vector<WalkEvidence> evidence;
  std::vector<char> right, is_elsewhere, frame_passes;
  for (const auto& walk : walks) {
    for (size_t i = 0; i < walk.size(); ++i) {
      for (int g = 1; g <= max_gap && static_cast<size_t>(g) <= i; ++g) {
        const WalkFrame& before = walk[i - static_cast<size_t>(g)];
        const auto add = [&](const CalibrationPose* last, const CalibrationPose* p) {
          if (last == nullptr || p == nullptr) return;
          evidence.push_back(walk_evidence(frame.logit(p->evidence), last->cam_from_world, p->cam_from_world, g));
          right.push_back(p->right ? 1 : 0);
          is_elsewhere.push_back(p->elsewhere ? 1 : 0);
          frame_passes.push_back(frame.probability(p->evidence) >= frame.threshold ? 1 : 0);
        };
        // A walk on its way: the last trusted pose right.
        if (before.as_is != nullptr && before.as_is->right) {
          add(before.as_is, walk[i].as_is);
          add(before.as_is, walk[i].elsewhere);
        }
        // A walk gone astray: a wrong "elsewhere" pose the frame rule reported became the last
        // trusted one, and the walk goes on where the map does not hold its view (a consistent
        // look-alike trajectory must not carry itself).
        const CalibrationPose* astray = before.elsewhere;
        if (astray != nullptr && !astray->right && frame.probability(astray->evidence) >= frame.threshold) {
          add(astray, walk[i].elsewhere);
        }
      }
    }
  }
  fit.num_samples = static_cast<int64_t>(evidence.size());
  fit.num_right = std::count(right.begin(), right.end(), 1);
  fit.num_elsewhere = std::count(is_elsewhere.begin(), is_elsewhere.end(), 1);
  if (fit.num_samples < options.min_poses || fit.num_right == fit.num_samples || fit.num_right == 0) return fit;
  fit.calibration = fit_walk_calibration(evidence, right, scales);
  // The operating point is set on the samples the frame rule does not report: what the walk rule
  // adds must itself be right at the target precision, and add at most the allowed share of
  // "elsewhere" poses.
  std::vector<double> p, p_added, p_elsewhere_added;
  std::vector<char> right_added;
  for (size_t i = 0; i < evidence.size(); ++i) {
    p.push_back(fit.calibration.probability(evidence[i]));
    if (frame_passes[i]) continue;
    p_added.push_back(p.back());
    right_added.push_back(right[i]);
    if (is_elsewhere[i]) p_elsewhere_added.push_back(p.back());
  }
  fit.precision_threshold =
      p_added.empty() ? 0.0 : lmb::precision_threshold(p_added, right_added, options.target_precision);
  fit.elsewhere_threshold = pass_share_threshold(
      p_elsewhere_added, std::max<int64_t>(fit.num_elsewhere, static_cast<int64_t>(p_elsewhere_added.size())),
      options.max_elsewhere_share);
  fit.calibration.threshold = std::max(fit.precision_threshold, fit.elsewhere_threshold);
  fit.calibration.target_precision = options.target_precision;
  fit.calibration.check("walk calibration");
  for (size_t i = 0; i < p.size(); ++i) {
    if (p[i] < fit.calibration.threshold && !frame_passes[i]) continue;
    ++fit.passed;
    fit.passed_right += right[i];
    fit.elsewhere_passed += is_elsewhere[i];
  }
  fit.fitted = true;
  return fit;
}

}  // namespace lmb
