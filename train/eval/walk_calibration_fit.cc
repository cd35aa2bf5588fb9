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

// The agreement tolerances (infer/walk_confidence.h) measured on the map: noise, the
// target_precision-quantile of the right "as is" calibration poses' errors against their map
// poses; step, the same quantile of the truth's motion between consecutive frames of a map
// session (every map-session frame, in map order). False when fewer than min_poses right poses or
// no step are there to measure.
bool fit_agreement(const LandmarkMap& map, const CalibrationFit& frame_fit, const PoseCalibrationOptions& options,
                   WalkCalibration* out) {
  std::vector<double> noise_m, noise_deg, step_m, step_deg;
  for (const CalibrationPose& p : frame_fit.poses) {
    if (p.elsewhere || !p.right) continue;
    noise_m.push_back(position_error(p.cam_from_world, map.frames[p.frame].cam_from_world));
    noise_deg.push_back(rotation_error_deg(p.cam_from_world, map.frames[p.frame].cam_from_world));
  }
  std::map<int32_t, const MapFrame*> previous;  // per map session, its latest frame so far
  for (const MapFrame& f : map.frames) {
    if (f.is_query) continue;
    const auto it = previous.find(f.session);
    if (it != previous.end()) {
      step_m.push_back(position_error(it->second->cam_from_world, f.cam_from_world));
      step_deg.push_back(rotation_error_deg(it->second->cam_from_world, f.cam_from_world));
    }
    previous[f.session] = &f;
  }
  if (static_cast<int64_t>(noise_m.size()) < options.min_poses || step_m.empty()) return false;
  const double q = options.target_precision;
  // Floors: a pose is never asked to agree more tightly than 1 mm and 0.01 degrees.
  out->agreement_noise_m = std::max(1e-3, quantile(noise_m, q));
  out->agreement_noise_deg = std::max(0.01, quantile(noise_deg, q));
  out->agreement_step_m = quantile(step_m, q);
  out->agreement_step_deg = quantile(step_deg, q);
  return true;
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
    j["adds"] = calibration.adds;
    j["agreement"] = calibration.has_agreement() ? nlohmann::json{{"noise_m", calibration.agreement_noise_m},
                                                                  {"noise_deg", calibration.agreement_noise_deg},
                                                                  {"step_m", calibration.agreement_step_m},
                                                                  {"step_deg", calibration.agreement_step_deg}}
                                                 : nlohmann::json(nullptr);
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
  WalkCalibration scales;
  scales.max_gap = max_gap;
  const bool agreement = fit_agreement(map, frame_fit, options, &scales);
  // Without a walk rule to fit, the calibration is the agreement alone (or nothing).
  const auto agreement_only = [&](WalkCalibrationFit f) {
    if (!agreement) return f;
    f.calibration = scales;
    f.calibration.adds = false;
    f.calibration.threshold = 1.0;
    f.calibration.target_precision = options.target_precision;
    f.calibration.check("walk calibration");
    f.fitted = true;
    return f;
  };
  if (steps_m.empty()) return agreement_only(fit);
  scales.translation_scale_m = std::max(1e-3, median(steps_m));
  scales.rotation_scale_deg = std::max(0.05, median(steps_deg));

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
  if (fit.num_samples < options.min_poses || fit.num_right == fit.num_samples || fit.num_right == 0) {
    return agreement_only(fit);
  }
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
