// The walk confidence (infer/walk_confidence.h): the evidence of a step against hand-worked
// values, the fit's direction on synthetic walks (a continuing pose is trusted, a jump is not),
// the tracker's rules (a right walk keeps reporting, a jump to a look-alike is refused on the jump,
// a lost walk falls back to the frame rule; agreement refuses a pose that disagrees with the frame
// before it whatever its own evidence) and monotonicity in the inlier support and the step.
#include "infer/walk_confidence.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

Rigid3d pose_at(double x, double yaw_deg = 0.0) {
  // A camera centred at (x, 0, 0), turned by yaw about the vertical.
  const Eigen::Quaterniond q(Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitY()));
  return Rigid3d(q, -(q * Eigen::Vector3d(x, 0, 0)));
}

PoseEvidence evidence_with(int inliers) {
  PoseEvidence e;
  e.num_keypoints = 400;
  e.num_correspondences = 200;
  e.num_inliers = inliers;
  e.inlier_rank = 0.7;
  e.spread = 0.5;
  return e;
}

// A frame calibration that reads the inlier count alone: logit = -4 + log(1 + inliers), so 20
// inliers give p = sigma(-0.955) = 0.28 and 80 give sigma(0.394) = 0.60; threshold 0.5.
PoseCalibration frame_calibration() {
  PoseCalibration c;
  c.weights[0] = 1.0;
  c.bias = -4.0;
  c.threshold = 0.5;
  return c;
}

// Synthetic walk samples: right poses step about 0.1 m a frame, wrong ones jump 2-10 m; the frame
// evidence of right poses is higher on average, and the ranges overlap. Fitted, the model trusts a continuing pose and
// refuses a jump.
WalkCalibration fitted_walk() {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<WalkEvidence> e;
  std::vector<char> right;
  for (int i = 0; i < 400; ++i) {
    WalkEvidence w;
    const bool r = i % 2 == 0;
    w.frame_logit = (r ? -2.0 : -4.0) + 4.0 * u(rng);
    w.frames_elapsed = 1 + i % 3;
    w.translation_step_m = r ? 0.05 + 0.1 * u(rng) : 2.0 + 8.0 * u(rng);
    w.rotation_step_deg = r ? 1.0 * u(rng) : 5.0 + 40.0 * u(rng);
    e.push_back(w);
    right.push_back(r ? 1 : 0);
  }
  WalkCalibration scales;
  scales.translation_scale_m = 0.1;
  scales.rotation_scale_deg = 0.5;
  scales.max_gap = 3;
  WalkCalibration c = fit_walk_calibration(e, right, scales);
  c.threshold = 0.5;
  return c;
}

TEST(WalkEvidence, StepsPerFrameFromTheLastTrustedPose) {
  const WalkEvidence e = walk_evidence(1.5, pose_at(0.0), pose_at(0.6, 12.0), 3);
  EXPECT_DOUBLE_EQ(e.frame_logit, 1.5);
  EXPECT_EQ(e.frames_elapsed, 3);
  EXPECT_NEAR(e.translation_step_m, 0.2, 1e-12);
  EXPECT_NEAR(e.rotation_step_deg, 4.0, 1e-9);
  EXPECT_THROW(walk_evidence(0.0, pose_at(0), pose_at(1), 0), Error);

  WalkCalibration c;
  c.translation_scale_m = 0.1;
  c.rotation_scale_deg = 2.0;
  const auto f = c.features(e);
  EXPECT_DOUBLE_EQ(f[0], 1.5);
  EXPECT_NEAR(f[1], std::log1p(2.0), 1e-12);
  EXPECT_NEAR(f[2], std::log1p(2.0), 1e-9);
  EXPECT_NEAR(f[3], std::log(3.0), 1e-12);
  // A pose without a finite logit reads as the least evidence.
  WalkEvidence none = e;
  none.frame_logit = -std::numeric_limits<double>::infinity();
  EXPECT_DOUBLE_EQ(c.features(none)[0], -30.0);
}

TEST(WalkCalibration, FitTrustsContinuingPosesAndRefusesJumps) {
  const WalkCalibration c = fitted_walk();
  EXPECT_EQ(c.num_samples, 400);
  EXPECT_EQ(c.num_positive, 200);
  EXPECT_LT(c.weights[1], 0.0);  // a longer step is weaker evidence
  WalkEvidence near_step;
  near_step.frame_logit = -1.0;
  near_step.translation_step_m = 0.1;
  near_step.rotation_step_deg = 0.5;
  WalkEvidence jump = near_step;
  jump.translation_step_m = 4.0;
  jump.rotation_step_deg = 20.0;
  EXPECT_GT(c.probability(near_step), 0.9);
  EXPECT_LT(c.probability(jump), 0.1);
  // Deterministic: the same samples give the same bits.
  const WalkCalibration again = fitted_walk();
  EXPECT_EQ(again.bias, c.bias);
  for (int k = 0; k < WalkEvidence::kNumFeatures; ++k) EXPECT_EQ(again.weights[k], c.weights[k]);
}

TEST(WalkCalibration, ProbabilityIsMonotoneInTheSupportAndTheStep) {
  const WalkCalibration c = fitted_walk();
  const PoseCalibration frame = frame_calibration();
  ASSERT_GT(c.weights[0], 0.0);
  double last = 0.0;
  for (int inliers = 5; inliers <= 200; inliers += 5) {
    const double p = c.probability(walk_evidence(frame.logit(evidence_with(inliers)), pose_at(0), pose_at(0.1), 1));
    EXPECT_GE(p, last) << inliers << " inliers";
    last = p;
  }
  last = 1.0;
  for (double step = 0.0; step <= 10.0; step += 0.25) {
    const double p = c.probability(walk_evidence(frame.logit(evidence_with(40)), pose_at(0), pose_at(step), 1));
    EXPECT_LE(p, last) << step << " m";
    last = p;
  }
}

TEST(WalkTracker, ARightWalkKeepsReportingAndAJumpIsRefused) {
  const PoseCalibration frame = frame_calibration();
  WalkTracker tracker(frame, fitted_walk());
  // The first frame: the frame rule (80 inliers: p 0.60 >= 0.5).
  WalkVerdict v = tracker.update(true, pose_at(0.0), evidence_with(80));
  EXPECT_FALSE(v.continues);
  EXPECT_TRUE(v.localized);
  // The walk goes on with 20 inliers a frame: the frame rule alone would refuse each (p 0.28).
  ASSERT_LT(frame.probability(evidence_with(20)), frame.threshold);
  for (int i = 1; i <= 10; ++i) {
    v = tracker.update(true, pose_at(0.1 * i, 0.2 * i), evidence_with(20));
    EXPECT_TRUE(v.continues) << "frame " << i;
    EXPECT_TRUE(v.localized) << "frame " << i;
    EXPECT_TRUE(v.by_walk) << "frame " << i;
  }
  // A look-alike 6 m ahead with the walk's own evidence (20 inliers) is refused on the jump.
  v = tracker.update(true, pose_at(7.0), evidence_with(20));
  EXPECT_TRUE(v.continues);
  EXPECT_LT(v.walk_confidence, 0.5);  // the operating point
  EXPECT_FALSE(v.localized);
  // The walk resumes from its last trusted pose: the next right pose (two frames on) is reported.
  v = tracker.update(true, pose_at(1.2, 2.4), evidence_with(20));
  EXPECT_TRUE(v.continues);
  EXPECT_EQ(v.evidence.frames_elapsed, 2);
  EXPECT_TRUE(v.localized);
  // A pose far from the walk whose own evidence carries it (80 inliers: the frame rule reports it)
  // is a relocalization: reported, and the walk goes on from it.
  v = tracker.update(true, pose_at(20.0), evidence_with(80));
  EXPECT_TRUE(v.localized);
  EXPECT_FALSE(v.by_walk);
  ASSERT_TRUE(tracker.last_trusted().has_value());
  EXPECT_NEAR(tracker.last_trusted()->center().x(), 20.0, 1e-12);
}

TEST(WalkTracker, ALostWalkFallsBackToTheFrameRule) {
  const PoseCalibration frame = frame_calibration();
  const WalkCalibration walk = fitted_walk();
  WalkTracker tracker(frame, walk);
  ASSERT_TRUE(tracker.update(true, pose_at(0.0), evidence_with(80)).localized);
  // max_gap frames without a pose: the walk is lost.
  for (int i = 0; i < walk.max_gap; ++i) EXPECT_FALSE(tracker.update(false, Rigid3d(), PoseEvidence()).localized);
  EXPECT_FALSE(tracker.last_trusted().has_value());
  // The next frame is judged as a first frame: 20 inliers are not enough, 80 are.
  WalkVerdict v = tracker.update(true, pose_at(0.4), evidence_with(20));
  EXPECT_FALSE(v.continues);
  EXPECT_FALSE(v.localized);
  v = tracker.update(true, pose_at(0.5), evidence_with(80));
  EXPECT_FALSE(v.continues);
  EXPECT_TRUE(v.localized);
  // Without a walk calibration every frame is the frame rule's.
  WalkTracker frame_only(frame, std::nullopt);
  ASSERT_TRUE(frame_only.update(true, pose_at(0.0), evidence_with(80)).localized);
  v = frame_only.update(true, pose_at(0.1), evidence_with(20));
  EXPECT_FALSE(v.continues);
  EXPECT_FALSE(v.localized);
}

// Agreement alone (the walk rule not fitted): noise 0.02 m / 0.5 deg, step 0.05 m / 1 deg a frame.
WalkCalibration agreement_only() {
  WalkCalibration c;
  c.adds = false;
  c.threshold = 1.0;
  c.agreement_noise_m = 0.02;
  c.agreement_noise_deg = 0.5;
  c.agreement_step_m = 0.05;
  c.agreement_step_deg = 1.0;
  return c;
}

TEST(WalkCalibration, AgreementToleranceGrowsWithTheFramesApart) {
  const WalkCalibration c = agreement_only();
  // One frame apart: sqrt(2) * 0.02 + 0.05 = 0.0783 m; two: 0.1283 m.
  EXPECT_NEAR(c.agreement_tolerance_m(1), 0.078284, 1e-6);
  EXPECT_NEAR(c.agreement_tolerance_deg(0), 0.707107, 1e-6);
  EXPECT_TRUE(c.agrees(pose_at(0.0), pose_at(0.078), 1));
  EXPECT_FALSE(c.agrees(pose_at(0.0), pose_at(0.079), 1));
  EXPECT_TRUE(c.agrees(pose_at(0.0), pose_at(0.128), 2));
  EXPECT_FALSE(c.agrees(pose_at(0.0), pose_at(0.129), 2));
  // Rotation: sqrt(2) * 0.5 + 1 = 1.707 deg a frame apart.
  EXPECT_TRUE(c.agrees(pose_at(0.0), pose_at(0.0, 1.70), 1));
  EXPECT_FALSE(c.agrees(pose_at(0.0), pose_at(0.0, 1.71), 1));
  // Without agreement every pair agrees.
  EXPECT_TRUE(WalkCalibration().agrees(pose_at(0.0), pose_at(50.0, 90.0), 1));
  WalkCalibration bad = agreement_only();
  bad.agreement_step_m = -1.0;
  EXPECT_THROW(bad.check(), Error);
}

TEST(WalkTracker, AgreementRefusesAJumpTheFrameRuleWouldReport) {
  // Every pose has the frame rule's support (80 inliers): without agreement each is reported.
  const PoseCalibration frame = frame_calibration();
  WalkTracker tracker(frame, agreement_only());
  WalkVerdict v = tracker.update(true, pose_at(0.0), evidence_with(80));
  EXPECT_FALSE(v.compared);  // the walk's first frame: the frame rule alone
  EXPECT_TRUE(v.localized);
  // A right walk, 4 cm a frame, keeps reporting; the test applies from its 4th comparison on.
  for (int i = 1; i <= 5; ++i) {
    v = tracker.update(true, pose_at(0.04 * i, 0.3 * i), evidence_with(80));
    EXPECT_TRUE(v.compared && v.agrees) << "frame " << i;
    EXPECT_EQ(v.agreement_applies, i > WalkTracker::kMinComparisons) << "frame " << i;
    EXPECT_TRUE(v.localized) << "frame " << i;
    EXPECT_FALSE(v.by_walk) << "frame " << i;
  }
  // A look-alike 1.2 m away, with the frame rule's support, is refused on the jump ...
  v = tracker.update(true, pose_at(1.4), evidence_with(80));
  EXPECT_TRUE(v.compared && v.agreement_applies);
  EXPECT_FALSE(v.agrees);
  EXPECT_FALSE(v.localized);
  // ... and so is the right pose after it (it disagrees with the look-alike), until two
  // neighbouring right poses agree again.
  v = tracker.update(true, pose_at(0.28, 2.1), evidence_with(80));
  EXPECT_FALSE(v.localized);
  v = tracker.update(true, pose_at(0.32, 2.4), evidence_with(80));
  EXPECT_TRUE(v.agrees);
  EXPECT_TRUE(v.localized);
  // A pose that wanders 0.15 m from one frame to the next is refused: a right pose does not.
  v = tracker.update(true, pose_at(0.47, 2.4), evidence_with(80));
  EXPECT_FALSE(v.localized);
  // A frame with no pose in the max_gap (3) frames before it is judged by the frame rule alone.
  for (int i = 0; i < 3; ++i) EXPECT_FALSE(tracker.update(false, Rigid3d(), PoseEvidence()).localized);
  v = tracker.update(true, pose_at(5.0), evidence_with(80));
  EXPECT_FALSE(v.compared);
  EXPECT_TRUE(v.localized);
  // Within max_gap frames the tolerance grows with the frames apart: after one frame without a
  // pose, 0.12 m is within 2 frames' tolerance (0.128 m).
  EXPECT_FALSE(tracker.update(false, Rigid3d(), PoseEvidence()).localized);
  v = tracker.update(true, pose_at(5.12), evidence_with(80));
  EXPECT_TRUE(v.compared && v.agrees);
  EXPECT_TRUE(v.localized);
  // reset() forgets the estimated poses too.
  tracker.reset();
  EXPECT_FALSE(tracker.update(true, pose_at(9.0), evidence_with(80)).compared);
}

TEST(WalkTracker, AgreementBindsTheWalkRuleToo) {
  const PoseCalibration frame = frame_calibration();
  WalkCalibration walk = fitted_walk();
  walk.agreement_noise_m = 0.05;  // a frame apart: sqrt(2) * 0.05 + 0.05 = 0.1207 m
  walk.agreement_noise_deg = 1.0;
  walk.agreement_step_m = 0.05;
  walk.agreement_step_deg = 1.0;
  WalkTracker tracker(frame, walk);
  ASSERT_TRUE(tracker.update(true, pose_at(0.0), evidence_with(80)).localized);
  // 20 inliers: the walk rule reports poses that continue the walk and agree.
  WalkVerdict v;
  for (int i = 1; i <= 3; ++i) {
    v = tracker.update(true, pose_at(0.1 * i), evidence_with(20));
    EXPECT_TRUE(v.by_walk) << "frame " << i;
  }
  // A look-alike 3 m on: refused.
  EXPECT_FALSE(tracker.update(true, pose_at(3.3), evidence_with(20)).localized);
  // The next pose continues the trusted one (the walk rule's probability passes) but disagrees
  // with the look-alike estimated just before it: refused.
  v = tracker.update(true, pose_at(0.5), evidence_with(20));
  EXPECT_TRUE(v.continues);
  EXPECT_GE(v.walk_confidence, walk.threshold);
  EXPECT_TRUE(v.agreement_applies);
  EXPECT_FALSE(v.agrees);
  EXPECT_FALSE(v.localized);
  // The one after agrees with it and continues the walk: reported again.
  v = tracker.update(true, pose_at(0.58), evidence_with(20));
  EXPECT_TRUE(v.agrees);
  EXPECT_TRUE(v.localized);
}

TEST(WalkTracker, PhotosMetresApartKeepTheFrameRule) {
  // Right poses 2 m apart each frame disagree with each other: the walk does not move like the
  // map's walks, so the agreement never applies and the frame rule reports every pose.
  WalkTracker tracker(frame_calibration(), agreement_only());
  for (int i = 0; i < 8; ++i) {
    const WalkVerdict v = tracker.update(true, pose_at(2.0 * i), evidence_with(80));
    EXPECT_EQ(v.compared, i > 0) << "frame " << i;
    EXPECT_FALSE(v.agreement_applies) << "frame " << i;
    EXPECT_TRUE(v.localized) << "frame " << i;
  }
}

TEST(WalkCalibration, InvalidFieldsAreNamed) {
  WalkCalibration c;
  c.translation_scale_m = 0.0;
  EXPECT_THROW(c.check(), Error);
  c = WalkCalibration();
  c.max_gap = 0;
  EXPECT_THROW(c.check(), Error);
  c = WalkCalibration();
  c.weights[2] = std::nan("");
  try {
    c.check();
    FAIL() << "a NaN weight passed";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("log_rotation_step"), std::string::npos) << e.what();
  }
  EXPECT_THROW(fit_walk_calibration({}, {}, WalkCalibration()), Error);
}

}  // namespace
}  // namespace lmb
