// The pose confidence's parts (infer/pose_confidence.h): the evidence of a pose against hand
// counts, the logistic fit (deterministic, separable data, recovery of known weights) and the
// operating point for precision against a hand-worked example.
#include "infer/pose_confidence.h"

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

Camera camera_640x480() {
  Camera c;
  c.model = CameraModel::kPinhole;
  c.width = 640;
  c.height = 480;
  c.params = {500, 500, 320, 240};
  return c;
}

TEST(PoseEvidence, CountsRanksAndSpreadOfAKnownPose) {
  const Camera camera = camera_640x480();
  // 8 correspondences; the inliers are 0, 1, 2 and 5. Quality ranks them 5 > 0 > 1 > ... (ties
  // in input order).
  std::vector<Eigen::Vector2d> pixels = {{10, 10},   {630, 10},  {10, 470}, {320, 240},
                                         {320, 250}, {630, 470}, {20, 20},  {30, 30}};
  std::vector<double> quality = {0.9, 0.8, 0.1, 0.1, 0.1, 1.0, 0.1, 0.1};
  PoseResult pose;
  pose.inlier_mask = {1, 1, 1, 0, 0, 1, 0, 0};
  pose.num_inliers = 4;
  pose.stats.num_data = 8;
  pose.stats.runner_up_inliers = 2;
  const PoseEvidence e = pose_evidence(camera, pixels, quality, pose, 32);
  EXPECT_EQ(e.num_inliers, 4);
  EXPECT_EQ(e.num_correspondences, 8);
  EXPECT_EQ(e.num_keypoints, 32);
  EXPECT_EQ(e.runner_up_inliers, 2);
  // Order: 5 (rank 0), 0 (1), 1 (2), 2 (3: first of the 0.1 ties), 3, 4, 6, 7.
  EXPECT_DOUBLE_EQ(e.inlier_rank, ((1 - 0 / 8.0) + (1 - 1 / 8.0) + (1 - 2 / 8.0) + (1 - 3 / 8.0)) / 4);
  // The four corners: 4 of 16 cells.
  EXPECT_DOUBLE_EQ(e.spread, 4.0 / 16);
  const auto f = e.features();
  EXPECT_DOUBLE_EQ(f[0], std::log1p(4.0));
  EXPECT_DOUBLE_EQ(f[1], 0.5);
  EXPECT_DOUBLE_EQ(f[2], 0.5);
  EXPECT_DOUBLE_EQ(f[3], e.inlier_rank);
  EXPECT_DOUBLE_EQ(f[4], 0.25);
  EXPECT_DOUBLE_EQ(f[5], 8.0 / 32);
  EXPECT_DOUBLE_EQ(f[6], std::log1p(8.0));

  // No order: rank 0.5. No inliers: every feature 0 and probability 0.
  EXPECT_DOUBLE_EQ(pose_evidence(camera, pixels, {}, pose, 32).inlier_rank, 0.5);
  PoseResult none;
  none.inlier_mask.assign(8, 0);
  none.stats.num_data = 8;
  const PoseEvidence z = pose_evidence(camera, pixels, quality, none, 32);
  for (double v : z.features()) EXPECT_EQ(v, 0.0);
  PoseCalibration c;
  c.bias = 100;
  EXPECT_EQ(c.probability(z), 0.0);

  EXPECT_THROW(pose_evidence(camera, pixels, {1.0}, pose, 32), Error);
  pixels.pop_back();
  EXPECT_THROW(pose_evidence(camera, pixels, {}, pose, 32), Error);
}

PoseEvidence evidence_of(int inliers, double spread, int runner_up) {
  PoseEvidence e;
  e.num_keypoints = 400;
  e.num_correspondences = 200;
  e.num_inliers = inliers;
  e.runner_up_inliers = runner_up;
  e.spread = spread;
  return e;
}

TEST(PoseCalibration, FitIsDeterministicAndSeparatesSeparableData) {
  // Right poses have 40 to 80 inliers, wrong ones 4 to 20; spread is noise.
  std::mt19937_64 rng(7);
  std::uniform_int_distribution<int> inliers(4, 80);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<PoseEvidence> evidence;
  std::vector<char> right;
  while (evidence.size() < 400) {
    const int n = inliers(rng);
    const double spread = unit(rng);
    if (n > 20 && n < 40) continue;
    evidence.push_back(evidence_of(n, spread, 0));
    right.push_back(n >= 40);
  }
  const PoseCalibration a = fit_pose_calibration(evidence, right);
  const PoseCalibration b = fit_pose_calibration(evidence, right);
  EXPECT_EQ(0, std::memcmp(a.weights.data(), b.weights.data(), sizeof(a.weights)));
  EXPECT_EQ(a.bias, b.bias);
  EXPECT_EQ(a.num_samples, 400);
  EXPECT_EQ(a.num_positive, std::count(right.begin(), right.end(), 1));
  // Every right pose scores above every wrong one, on both sides of 0.5.
  for (size_t i = 0; i < evidence.size(); ++i) {
    const double p = a.probability(evidence[i]);
    if (right[i]) {
      EXPECT_GT(p, 0.5) << evidence[i].num_inliers;
    } else {
      EXPECT_LT(p, 0.5) << evidence[i].num_inliers;
    }
  }
  EXPECT_GT(a.weights[0], 0.0);  // more inliers, more likely right
  // The operating point at precision 1 keeps every right pose and no wrong one.
  std::vector<double> p;
  for (const PoseEvidence& e : evidence) p.push_back(a.probability(e));
  const double t = precision_threshold(p, right, 1.0);
  for (size_t i = 0; i < evidence.size(); ++i) EXPECT_EQ(p[i] >= t, right[i] != 0);
}

TEST(PoseCalibration, FitRecoversKnownWeights) {
  // Labels drawn from a known logistic model over spread and the runner-up ratio (the other
  // features are constant): logit = -1 + 4 spread - 3 runner_up_ratio.
  constexpr double kBias = -1.0, kSpread = 4.0, kRunnerUp = -3.0;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::uniform_int_distribution<int> runner(0, 50);
  std::vector<PoseEvidence> evidence;
  std::vector<char> right;
  for (int i = 0; i < 40000; ++i) {
    const PoseEvidence e = evidence_of(50, unit(rng), runner(rng));
    const auto f = e.features();
    const double logit = kBias + kSpread * f[4] + kRunnerUp * f[2];
    evidence.push_back(e);
    right.push_back(unit(rng) < 1.0 / (1.0 + std::exp(-logit)));
  }
  PoseCalibrationFitOptions options;
  options.l2 = 1e-8;
  const PoseCalibration c = fit_pose_calibration(evidence, right, options);
  EXPECT_NEAR(c.weights[4], kSpread, 0.25);
  EXPECT_NEAR(c.weights[2], kRunnerUp, 0.25);
  for (int k : {0, 1, 3, 5, 6}) EXPECT_NEAR(c.weights[k], 0.0, 1e-9) << k;  // constant features
  // The constant features fold into the bias: the fitted logit at a point matches the truth.
  const PoseEvidence probe = evidence_of(50, 0.5, 10);
  const double truth = 1.0 / (1.0 + std::exp(-(kBias + kSpread * 0.5 + kRunnerUp * 0.2)));
  EXPECT_NEAR(c.probability(probe), truth, 0.03);
}

TEST(PoseCalibration, FitRejectsBadInput) {
  EXPECT_THROW(fit_pose_calibration({evidence_of(20, 0.5, 0)}, {1, 0}), Error);
  EXPECT_THROW(fit_pose_calibration({evidence_of(0, 0.5, 0)}, {1}), Error);  // no pose with inliers
  PoseCalibrationFitOptions bad;
  bad.l2 = 0;
  EXPECT_THROW(fit_pose_calibration({evidence_of(20, 0.5, 0)}, {1}, bad), Error);
  PoseCalibration c;
  c.threshold = 1.5;
  EXPECT_THROW(c.check(), Error);
  c.threshold = 0.5;
  c.weights[3] = std::nan("");
  EXPECT_THROW(c.check(), Error);
  c.weights[3] = 0;
  c.num_samples = 1;
  c.num_positive = 2;
  EXPECT_THROW(c.check(), Error);
}

TEST(PrecisionThreshold, KnownAnswer) {
  // Sorted by probability: 0.9 R, 0.8 R, 0.7 W, 0.6 R, 0.6 R, 0.5 W, 0.4 W.
  const std::vector<double> p = {0.6, 0.9, 0.4, 0.7, 0.8, 0.5, 0.6};
  const std::vector<char> right = {1, 1, 0, 0, 1, 0, 1};
  // Prefix precisions: 0.9: 1/1, 0.8: 2/2, 0.7: 2/3, 0.6: 4/5, 0.5: 4/6, 0.4: 4/7.
  EXPECT_DOUBLE_EQ(precision_threshold(p, right, 1.0), 0.8);
  EXPECT_DOUBLE_EQ(precision_threshold(p, right, 0.8), 0.6);  // the two 0.6 pass together
  EXPECT_DOUBLE_EQ(precision_threshold(p, right, 0.5), 0.4);
  EXPECT_DOUBLE_EQ(precision_threshold({0.3, 0.2}, {0, 1}, 0.95), 1.0);  // never reached
  EXPECT_THROW(precision_threshold(p, right, 0.0), Error);
  EXPECT_THROW(precision_threshold(p, {1}, 0.9), Error);
}

}  // namespace
}  // namespace lmb
