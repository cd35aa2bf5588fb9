#include "infer/pose_confidence.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "common/error.h"
#include "infer/detail/logistic_fit.h"

namespace lmb {

namespace {
constexpr int kF = PoseEvidence::kNumFeatures;
}  // namespace

std::array<double, PoseEvidence::kNumFeatures> PoseEvidence::features() const {
  std::array<double, kF> f{};
  if (num_inliers <= 0) return f;
  const double inliers = num_inliers;
  const double offered = num_correspondences;
  f[0] = std::log1p(inliers);
  f[1] = offered > 0 ? std::min(1.0, inliers / offered) : 0.0;
  f[2] = std::min(2.0, runner_up_inliers / inliers);
  f[3] = inlier_rank;
  f[4] = spread;
  f[5] = num_keypoints > 0 ? std::min(1.0, offered / num_keypoints) : 0.0;
  f[6] = std::log1p(offered);
  return f;
}

const std::array<const char*, PoseEvidence::kNumFeatures>& PoseEvidence::feature_names() {
  static const std::array<const char*, kF> names = {"log_inliers", "inlier_ratio",  "runner_up_ratio", "inlier_rank",
                                                    "spread",      "offered_share", "log_offered"};
  return names;
}

PoseEvidence pose_evidence(const Camera& camera, const std::vector<Eigen::Vector2d>& pixels,
                           const std::vector<double>& quality, const PoseResult& pose, int num_keypoints) {
  const size_t n = pixels.size();
  LMB_CHECK(pose.inlier_mask.size() == n, "pose_evidence: the pose has " << pose.inlier_mask.size()
                                                                         << " inlier flags for " << n
                                                                         << " correspondences");
  LMB_CHECK(quality.empty() || quality.size() == n,
            "pose_evidence: " << quality.size() << " quality values for " << n << " correspondences");
  LMB_CHECK(num_keypoints >= 0, "pose_evidence: num_keypoints = " << num_keypoints << " is negative");
  PoseEvidence e;
  e.num_keypoints = num_keypoints;
  e.num_correspondences = pose.stats.num_data;
  e.num_inliers = pose.num_inliers;
  e.runner_up_inliers = pose.stats.runner_up_inliers;
  if (pose.num_inliers <= 0 || n == 0) return e;

  // Ranks in decreasing quality, ties in input order (the PROSAC order of estimate_absolute_pose).
  if (!quality.empty()) {
    std::vector<int> order(n);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return quality[a] > quality[b]; });
    double sum = 0.0;
    int count = 0;
    for (size_t r = 0; r < n; ++r) {
      if (!pose.inlier_mask[order[r]]) continue;
      sum += 1.0 - static_cast<double>(r) / static_cast<double>(n);
      ++count;
    }
    if (count > 0) e.inlier_rank = sum / count;
  }
  constexpr int kGrid = 4;
  bool cell[kGrid][kGrid] = {};
  for (size_t i = 0; i < n; ++i) {
    if (!pose.inlier_mask[i]) continue;
    const int cx = std::clamp(static_cast<int>(pixels[i].x() / camera.width * kGrid), 0, kGrid - 1);
    const int cy = std::clamp(static_cast<int>(pixels[i].y() / camera.height * kGrid), 0, kGrid - 1);
    cell[cy][cx] = true;
  }
  int occupied = 0;
  for (const auto& row : cell) occupied += static_cast<int>(std::count(row, row + kGrid, true));
  e.spread = static_cast<double>(occupied) / (kGrid * kGrid);
  return e;
}

double PoseCalibration::probability(const PoseEvidence& evidence) const {
  if (evidence.num_inliers <= 0) return 0.0;
  return 1.0 / (1.0 + std::exp(-logit(evidence)));
}

double PoseCalibration::logit(const PoseEvidence& evidence) const {
  if (evidence.num_inliers <= 0) return -std::numeric_limits<double>::infinity();
  const auto f = evidence.features();
  double z = bias;
  for (int k = 0; k < kF; ++k) z += weights[k] * f[k];
  return z;
}

void PoseCalibration::check(const std::string& where) const {
  for (int k = 0; k < kF; ++k) {
    LMB_CHECK(std::isfinite(weights[k]),
              where << ": weight " << k << " (" << PoseEvidence::feature_names()[k] << ") is not finite");
  }
  LMB_CHECK(std::isfinite(bias), where << ": bias is not finite");
  LMB_CHECK(threshold >= 0.0 && threshold <= 1.0, where << ": threshold " << threshold << " is outside [0, 1]");
  LMB_CHECK(num_samples >= 0 && num_positive >= 0 && num_positive <= num_samples,
            where << ": counts " << num_positive << " right of " << num_samples << " samples are inconsistent");
  LMB_CHECK(target_precision >= 0.0 && target_precision <= 1.0,
            where << ": target_precision " << target_precision << " is outside [0, 1]");
}

void PoseCalibrationFitOptions::check() const {
  LMB_CHECK(std::isfinite(l2) && l2 > 0, "PoseCalibrationFitOptions.l2 must be > 0, got " << l2);
  LMB_CHECK(max_iterations >= 1, "PoseCalibrationFitOptions.max_iterations must be >= 1, got " << max_iterations);
}

PoseCalibration fit_pose_calibration(const std::vector<PoseEvidence>& evidence, const std::vector<char>& right,
                                     const PoseCalibrationFitOptions& options) {
  options.check();
  LMB_CHECK(evidence.size() == right.size(),
            "fit_pose_calibration: " << evidence.size() << " poses but " << right.size() << " labels");
  std::vector<std::array<double, kF>> x;
  std::vector<double> y;
  for (size_t i = 0; i < evidence.size(); ++i) {
    if (evidence[i].num_inliers <= 0) continue;
    x.push_back(evidence[i].features());
    y.push_back(right[i] ? 1.0 : 0.0);
  }
  LMB_CHECK(!x.empty(), "fit_pose_calibration: no pose with inliers among " << evidence.size() << " samples");
  PoseCalibration c;
  detail::fit_logistic<kF>(x, y, options.l2, options.max_iterations, &c.weights, &c.bias);
  c.num_samples = static_cast<int64_t>(x.size());
  c.num_positive = static_cast<int64_t>(std::count(y.begin(), y.end(), 1.0));
  c.check("fit_pose_calibration");
  return c;
}

double precision_threshold(const std::vector<double>& probability, const std::vector<char>& right,
                           double target_precision) {
  LMB_CHECK(probability.size() == right.size(),
            "precision_threshold: " << probability.size() << " probabilities but " << right.size() << " labels");
  LMB_CHECK(target_precision > 0.0 && target_precision <= 1.0,
            "precision_threshold: target precision " << target_precision << " is outside (0, 1]");
  std::vector<size_t> order(probability.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return probability[a] > probability[b]; });
  double best = 1.0;
  int64_t passed = 0, passed_right = 0;
  for (size_t k = 0; k < order.size();) {
    const double p = probability[order[k]];
    // A threshold passes every sample of equal probability at once.
    while (k < order.size() && probability[order[k]] == p) {
      ++passed;
      passed_right += right[order[k]] ? 1 : 0;
      ++k;
    }
    if (static_cast<double>(passed_right) >= target_precision * static_cast<double>(passed)) best = p;
  }
  return best;
}

}  // namespace lmb
