#include "infer/walk_confidence.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "infer/detail/logistic_fit.h"

namespace lmb {

namespace {
constexpr int kW = WalkEvidence::kNumFeatures;
constexpr double kMaxLogit = 30.0;
}  // namespace

const std::array<const char*, WalkEvidence::kNumFeatures>& WalkEvidence::feature_names() {
  static const std::array<const char*, kW> names = {"frame_logit", "log_translation_step", "log_rotation_step",
                                                    "log_frames_elapsed"};
  return names;
}

WalkEvidence walk_evidence(double frame_logit, const Rigid3d& last_trusted, const Rigid3d& pose,
                           int32_t frames_elapsed) {
  LMB_CHECK(frames_elapsed >= 1, "walk_evidence: frames_elapsed = " << frames_elapsed << " must be >= 1");
  WalkEvidence e;
  e.frame_logit = frame_logit;
  e.frames_elapsed = frames_elapsed;
  e.translation_step_m = position_error(pose, last_trusted) / frames_elapsed;
  e.rotation_step_deg = rotation_error_deg(pose, last_trusted) / frames_elapsed;
  return e;
}

std::array<double, WalkEvidence::kNumFeatures> WalkCalibration::features(const WalkEvidence& e) const {
  std::array<double, kW> f{};
  f[0] = std::isnan(e.frame_logit) ? -kMaxLogit : std::clamp(e.frame_logit, -kMaxLogit, kMaxLogit);
  f[1] = std::log1p(std::max(0.0, e.translation_step_m) / translation_scale_m);
  f[2] = std::log1p(std::max(0.0, e.rotation_step_deg) / rotation_scale_deg);
  f[3] = std::log(static_cast<double>(std::max(1, e.frames_elapsed)));
  // A non-finite step (a pose at infinity) reads as the largest jump a double holds.
  for (double& v : f) {
    if (!std::isfinite(v)) v = v < 0 ? -kMaxLogit : 1e3;
  }
  return f;
}

double WalkCalibration::probability(const WalkEvidence& e) const {
  const auto f = features(e);
  double z = bias;
  for (int k = 0; k < kW; ++k) z += weights[k] * f[k];
  return 1.0 / (1.0 + std::exp(-z));
}

double WalkCalibration::agreement_tolerance_m(int32_t g) const {
  return std::sqrt(2.0) * agreement_noise_m + static_cast<double>(g) * agreement_step_m;
}

double WalkCalibration::agreement_tolerance_deg(int32_t g) const {
  return std::sqrt(2.0) * agreement_noise_deg + static_cast<double>(g) * agreement_step_deg;
}

bool WalkCalibration::agrees(const Rigid3d& a, const Rigid3d& b, int32_t frames_apart) const {
  if (!has_agreement()) return true;
  const int32_t g = std::max(1, frames_apart);
  return position_error(a, b) <= agreement_tolerance_m(g) && rotation_error_deg(a, b) <= agreement_tolerance_deg(g);
}

void WalkCalibration::check(const std::string& where) const {
  for (const double v : {agreement_noise_m, agreement_noise_deg, agreement_step_m, agreement_step_deg}) {
    LMB_CHECK(std::isfinite(v) && v >= 0.0, where << ": agreement tolerance " << v << " must be finite and >= 0");
  }
  for (int k = 0; k < kW; ++k) {
    LMB_CHECK(std::isfinite(weights[k]),
              where << ": weight " << k << " (" << WalkEvidence::feature_names()[k] << ") is not finite");
  }
  LMB_CHECK(std::isfinite(bias), where << ": bias is not finite");
  LMB_CHECK(threshold >= 0.0 && threshold <= 1.0, where << ": threshold " << threshold << " is outside [0, 1]");
  LMB_CHECK(std::isfinite(translation_scale_m) && translation_scale_m > 0,
            where << ": translation_scale_m " << translation_scale_m << " must be finite and > 0");
  LMB_CHECK(std::isfinite(rotation_scale_deg) && rotation_scale_deg > 0,
            where << ": rotation_scale_deg " << rotation_scale_deg << " must be finite and > 0");
  LMB_CHECK(max_gap >= 1 && max_gap <= 1000, where << ": max_gap " << max_gap << " is outside 1..1000");
  LMB_CHECK(num_samples >= 0 && num_positive >= 0 && num_positive <= num_samples,
            where << ": counts " << num_positive << " right of " << num_samples << " samples are inconsistent");
  LMB_CHECK(target_precision >= 0.0 && target_precision <= 1.0,
            where << ": target_precision " << target_precision << " is outside [0, 1]");
}

WalkCalibration fit_walk_calibration(const std::vector<WalkEvidence>& evidence, const std::vector<char>& right,
                                     const WalkCalibration& scales, const PoseCalibrationFitOptions& options) {
  options.check();
  LMB_CHECK(evidence.size() == right.size(),
            "fit_walk_calibration: " << evidence.size() << " poses but " << right.size() << " labels");
  LMB_CHECK(!evidence.empty(), "fit_walk_calibration: no sample");
  // The scales, max_gap and agreement as given; the rule's own fields fitted below.
  WalkCalibration c = scales;
  c.threshold = 0.5;
  c.adds = true;
  c.target_precision = 0.0;
  c.check("fit_walk_calibration");
  std::vector<std::array<double, kW>> x;
  std::vector<double> y;
  for (size_t i = 0; i < evidence.size(); ++i) {
    x.push_back(c.features(evidence[i]));
    y.push_back(right[i] ? 1.0 : 0.0);
  }
  detail::fit_logistic<kW>(x, y, options.l2, options.max_iterations, &c.weights, &c.bias);
  c.num_samples = static_cast<int64_t>(x.size());
  c.num_positive = static_cast<int64_t>(std::count(y.begin(), y.end(), 1.0));
  c.check("fit_walk_calibration");
  return c;
}

WalkTracker::WalkTracker(const PoseCalibration& frame, const std::optional<WalkCalibration>& walk)
    : frame_(frame), walk_(walk) {
  frame_.check("walk tracker: frame calibration");
  if (walk_) walk_->check("walk tracker: walk calibration");
}

void WalkTracker::reset() {
  forget_trusted();
  forget_found();
  compared_ = disagreed_ = 0;
}

void WalkTracker::forget_trusted() {
  last_.reset();
  since_ = 0;
}

void WalkTracker::forget_found() {
  last_found_.reset();
  since_found_ = 0;
}

WalkVerdict WalkTracker::update(bool success, const Rigid3d& cam_from_world, const PoseEvidence& evidence) {
  WalkVerdict v;
  const bool has_pose = success && evidence.num_inliers > 0;
  const int32_t elapsed = since_ + 1;
  v.continues = walk_ && last_ && elapsed <= walk_->max_gap;
  bool frame_ok = false, walk_ok = false;
  if (has_pose) {
    v.frame_confidence = frame_.probability(evidence);
    frame_ok = v.frame_confidence >= frame_.threshold;
    if (walk_ && walk_->has_agreement() && last_found_ && since_found_ + 1 <= walk_->max_gap) {
      v.compared = true;
      v.agrees = walk_->agrees(*last_found_, cam_from_world, since_found_ + 1);
      v.agreement_applies = compared_ >= kMinComparisons && 2 * disagreed_ <= compared_;
      ++compared_;
      disagreed_ += v.agrees ? 0 : 1;
    }
    if (v.continues && walk_->adds) {
      v.evidence = walk_evidence(frame_.logit(evidence), *last_, cam_from_world, elapsed);
      v.walk_confidence = walk_->probability(v.evidence);
      walk_ok = v.walk_confidence >= walk_->threshold;
    }
    // A pose that disagrees with the frame before is refused by either rule.
    const bool refused = v.agreement_applies && !v.agrees;
    frame_ok = frame_ok && !refused;
    walk_ok = walk_ok && !refused;
  }
  v.localized = frame_ok || walk_ok;
  v.by_walk = walk_ok && !frame_ok;
  if (has_pose) {
    last_found_ = cam_from_world;
    since_found_ = 0;
  } else if (last_found_ && ++since_found_ >= (walk_ ? walk_->max_gap : 1)) {
    forget_found();
  }
  if (v.localized) {
    last_ = cam_from_world;
    since_ = 0;
  } else if (last_) {
    ++since_;
    // The walk is lost once the last trusted pose is further back than the walk rule reads.
    if (!walk_ || since_ >= walk_->max_gap) forget_trusted();
  }
  return v;
}

}  // namespace lmb
