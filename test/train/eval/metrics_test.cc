#include "train/eval/metrics.h"

#include <cmath>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

KeypointRanking ranking(landmark_t truth, std::vector<landmark_t> list) {
  KeypointRanking r;
  r.truth = truth;
  double score = 10.0;
  for (landmark_t l : list) r.candidates.push_back(RankedCandidate{l, score--});
  return r;
}

// Four keypoints with truth (ranks 1, 2, absent, empty list) and two background keypoints.
std::vector<KeypointRanking> hand_case() {
  return {ranking(5, {5, 7}), ranking(3, {7, 3, 9}),           ranking(4, {1, 2}),
          ranking(8, {}),     ranking(kInvalidLandmarkId, {}), ranking(kInvalidLandmarkId, {2})};
}

TEST(EvaluateRetrieval, PrecisionAndMrrOnHandCase) {
  const RetrievalMetrics m = evaluate_retrieval(hand_case());
  EXPECT_EQ(m.num_keypoints, 6);
  EXPECT_EQ(m.num_with_truth, 4);
  EXPECT_DOUBLE_EQ(m.precision_at_1, 0.25);
  EXPECT_DOUBLE_EQ(m.mrr, (1.0 + 0.5) / 4.0);
}

TEST(EvaluateRetrieval, MissRateCurveOnHandCase) {
  const RetrievalMetrics m = evaluate_retrieval(hand_case());
  ASSERT_EQ(m.miss_rate_curve.size(), 4u);
  // n = 1: 3 returned, 1 hit; n = 2: 6 returned, 2 hits; n = 3: 7 returned, 2 hits; 4 keypoints.
  const double fppi[] = {0.0, 0.5, 1.0, 1.25};
  const double miss[] = {1.0, 0.75, 0.5, 0.5};
  for (int n = 0; n < 4; ++n) {
    EXPECT_EQ(m.miss_rate_curve[n].n, n);
    EXPECT_DOUBLE_EQ(m.miss_rate_curve[n].fppi, fppi[n]) << n;
    EXPECT_DOUBLE_EQ(m.miss_rate_curve[n].miss_rate, miss[n]) << n;
  }
  // 0.1 lies before the first positive FPPI: Dollar's step from (0, 1).
  EXPECT_DOUBLE_EQ(m.miss_rate_at_fppi_0_1, 1.0);
  // 1 is exactly a curve point.
  EXPECT_DOUBLE_EQ(m.miss_rate_at_fppi_1, 0.5);
  // 10 is past the end of the curve: its last miss rate.
  EXPECT_DOUBLE_EQ(m.miss_rate_at_fppi_10, 0.5);
  // Between (0.5, 0.75) and (1, 0.5), interpolated in log10(FPPI).
  const double t = std::log10(0.75 / 0.5) / std::log10(2.0);
  EXPECT_NEAR(miss_rate_at_fppi(m.miss_rate_curve, 0.75), 0.75 - 0.25 * t, 1e-12);
  EXPECT_NEAR(miss_rate_at_fppi(m.miss_rate_curve, 0.5), 0.75, 1e-12);
  // Log-average over 10^-2 .. 10^0: seven references below 0.5 give 1, 10^-0.25 interpolates, 1 gives 0.5.
  const double r = std::pow(10.0, -0.25);
  const double mr = 0.75 - 0.25 * std::log10(r / 0.5) / std::log10(2.0);
  EXPECT_NEAR(m.log_average_miss_rate, std::exp((std::log(mr) + std::log(0.5)) / 9.0), 1e-12);
}

TEST(EvaluateRetrieval, PerfectRankingHasNoMissesOrFalsePositivesAtRankOne) {
  std::vector<KeypointRanking> r;
  for (landmark_t l = 0; l < 10; ++l) r.push_back(ranking(l, {l, l + 100}));
  const RetrievalMetrics m = evaluate_retrieval(r);
  EXPECT_DOUBLE_EQ(m.precision_at_1, 1.0);
  EXPECT_DOUBLE_EQ(m.mrr, 1.0);
  EXPECT_DOUBLE_EQ(m.miss_rate_curve[1].fppi, 0.0);
  EXPECT_DOUBLE_EQ(m.miss_rate_curve[1].miss_rate, 0.0);
  EXPECT_DOUBLE_EQ(m.miss_rate_at_fppi_0_1, 0.0);
  EXPECT_DOUBLE_EQ(m.miss_rate_at_fppi_10, 0.0);
}

TEST(EvaluateRetrieval, NoKeypointWithTruth) {
  const RetrievalMetrics m = evaluate_retrieval({ranking(kInvalidLandmarkId, {1})});
  EXPECT_EQ(m.num_with_truth, 0);
  EXPECT_DOUBLE_EQ(m.precision_at_1, 0.0);
  EXPECT_DOUBLE_EQ(m.mrr, 0.0);
  ASSERT_EQ(m.miss_rate_curve.size(), 1u);
  EXPECT_DOUBLE_EQ(m.miss_rate_at_fppi_1, 1.0);
}

// Accepted matches: 3 keypoints with truth (right, wrong, rejected), 3 background (one accepted,
// two rejected).
TEST(EvaluateMatches, PrecisionRecallAndBackgroundRejection) {
  const MatchMetrics m = evaluate_matches({{5, 5},
                                           {7, 3},
                                           {kInvalidLandmarkId, 4},
                                           {2, kInvalidLandmarkId},
                                           {kInvalidLandmarkId, kInvalidLandmarkId},
                                           {kInvalidLandmarkId, kInvalidLandmarkId}});
  EXPECT_EQ(m.num_keypoints, 6);
  EXPECT_EQ(m.num_with_truth, 3);
  EXPECT_EQ(m.num_background, 3);
  EXPECT_EQ(m.num_accepted, 3);
  EXPECT_EQ(m.num_accepted_correct, 1);
  EXPECT_DOUBLE_EQ(m.match_precision, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(m.match_recall, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(m.background_rejection_rate, 2.0 / 3.0);
  const MatchMetrics none = evaluate_matches({});
  EXPECT_EQ(none.match_precision, 0.0);
  EXPECT_EQ(none.match_recall, 0.0);
  EXPECT_EQ(none.background_rejection_rate, 0.0);
}

TEST(PoseThresholdsTest, ParsesPairsAndRejectsTheRest) {
  const auto t = parse_pose_thresholds("0.2,5;1,2;0.05,1", "test");
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(t[1].max_position_error_m, 1.0);
  EXPECT_EQ(t[1].max_rotation_error_deg, 2.0);
  EXPECT_EQ(t[2].max_position_error_m, 0.05);
  for (const char* bad : {"", "0.2", "0.2,5;", "0.2,x", "-1,5", "0.2,inf", "a,b", "0.2,5,1"}) {
    EXPECT_THROW(parse_pose_thresholds(bad, "test"), Error) << bad;
  }
}

TEST(EvaluateRetrieval, RejectsDuplicateAndInvalidCandidates) {
  EXPECT_THROW(evaluate_retrieval({ranking(1, {2, 1, 2})}), Error);
  EXPECT_THROW(evaluate_retrieval({ranking(1, {kInvalidLandmarkId})}), Error);
  EXPECT_THROW(miss_rate_at_fppi({}, 1.0), Error);
  EXPECT_THROW(miss_rate_at_fppi({MissRatePoint{}}, 0.0), Error);
}

// ---------------------------------------------------------------------------------------------

Rigid3d pose_with_center(const Eigen::Quaterniond& q, const Eigen::Vector3d& center) {
  return Rigid3d(q, -(q * center));
}

Eigen::Quaterniond rot_deg(double deg, const Eigen::Vector3d& axis) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(deg * M_PI / 180.0, axis.normalized()));
}

FrameOutcome frame(bool localized, const Rigid3d& estimate, double confidence, int correspondences, int inliers) {
  FrameOutcome f;
  f.localized = localized;
  // Ground truth: a generic pose; the estimate is expressed relative to it.
  const Rigid3d truth = pose_with_center(rot_deg(30, {1, 2, 3}), {4, -1, 2});
  f.true_cam_from_world = truth;
  // estimate = delta * truth keeps the rotation error of delta; the centre offset is set below.
  f.cam_from_world = estimate;
  f.confidence = confidence;
  f.num_correspondences = correspondences;
  f.num_inliers = inliers;
  f.match_ms = 2.0;
  f.total_ms = 3.0;
  return f;
}

// An estimate whose centre is `offset` from the truth's and whose rotation differs by `deg`.
Rigid3d perturbed(double deg, const Eigen::Vector3d& offset) {
  const Rigid3d truth = pose_with_center(rot_deg(30, {1, 2, 3}), {4, -1, 2});
  return pose_with_center(rot_deg(deg, {0, 0, 1}) * truth.rotation, truth.center() + offset);
}

std::vector<FrameOutcome> pose_case() {
  return {
      frame(true, perturbed(1.0, {0.05, 0, 0}), 100, 200, 100),   // correct
      frame(true, perturbed(0.0, {0, 0.2, 0}), 50, 20, 10),       // correct: exactly 20 cm
      frame(true, perturbed(5.0, {0, 0, 0}), 80, 10, 5),          // correct: exactly 5 deg
      frame(true, perturbed(0.0, {0, 0, 0.2000001}), 90, 10, 2),  // wrong: just over 20 cm
      frame(true, perturbed(5.001, {0, 0, 0}), 50, 10, 0),        // wrong: just over 5 deg
      frame(false, Rigid3d(), 1000, 30, 30),                      // not localized
  };
}

TEST(EvaluatePoses, ErrorsAndThresholdsOnHandCase) {
  const PoseMetrics m = evaluate_poses(pose_case());
  EXPECT_EQ(m.num_frames, 6);
  EXPECT_EQ(m.num_localized, 5);
  EXPECT_EQ(m.num_correct, 3);
  EXPECT_EQ(m.correct, (std::vector<char>{1, 1, 1, 0, 0, 0}));
  EXPECT_DOUBLE_EQ(m.recall, 0.5);
  EXPECT_NEAR(m.position_error_m[0], 0.05, 1e-9);
  EXPECT_NEAR(m.rotation_error_deg[0], 1.0, 1e-9);
  EXPECT_NEAR(m.position_error_m[1], 0.2, 1e-12);
  EXPECT_NEAR(m.rotation_error_deg[2], 5.0, 1e-9);
  EXPECT_TRUE(std::isnan(m.position_error_m[5]));
  // Medians over the 5 localized frames: positions {0.05, 0.2, 0, 0.2000001, 0}, rotations {1, 0, 5, 0, 5.001}.
  EXPECT_NEAR(m.median_position_error_m, 0.05, 1e-9);
  EXPECT_NEAR(m.median_rotation_error_deg, 1.0, 1e-9);
  // Inlier ratios 0.5, 0.5, 0.5, 0.2, 0, and 0 for the frame not localized.
  EXPECT_NEAR(m.mean_inlier_ratio, 1.7 / 6.0, 1e-12);
  EXPECT_DOUBLE_EQ(m.mean_match_ms, 2.0);
  EXPECT_DOUBLE_EQ(m.mean_total_ms, 3.0);
}

TEST(EvaluatePoses, PrecisionRecallCurveAndAuc) {
  const PoseMetrics m = evaluate_poses(pose_case());
  // Confidences: 100 (correct), 90 (wrong), 80 (correct), 50 (correct + wrong, entering together).
  ASSERT_EQ(m.pr_curve.size(), 5u);
  const double recall[] = {0.0, 1.0 / 6, 1.0 / 6, 2.0 / 6, 3.0 / 6};
  const double precision[] = {1.0, 1.0, 0.5, 2.0 / 3, 3.0 / 5};
  const double threshold[] = {100, 100, 90, 80, 50};
  for (int i = 0; i < 5; ++i) {
    EXPECT_NEAR(m.pr_curve[i].recall, recall[i], 1e-12) << i;
    EXPECT_NEAR(m.pr_curve[i].precision, precision[i], 1e-12) << i;
    EXPECT_DOUBLE_EQ(m.pr_curve[i].threshold, threshold[i]) << i;
  }
  // Trapezoids: 1/6 * 1 + 0 + 1/6 * (1/2 + 2/3) / 2 + 1/6 * (2/3 + 3/5) / 2 = 133/360.
  EXPECT_NEAR(m.auc, 133.0 / 360.0, 1e-12);
}

TEST(EvaluatePoses, ThresholdsAreConfigurable) {
  PoseThresholds loose;
  loose.max_position_error_m = 0.3;
  loose.max_rotation_error_deg = 6.0;
  const PoseMetrics m = evaluate_poses(pose_case(), loose);
  EXPECT_EQ(m.num_correct, 5);
  // All localized frames correct: the curve ends at recall 5/6 with precision 1, AUC = 5/6.
  EXPECT_NEAR(m.auc, 5.0 / 6.0, 1e-12);
  // The 20 cm / 5 deg recall does not follow the thresholds.
  EXPECT_DOUBLE_EQ(m.recall, 5.0 / 6.0);
  EXPECT_DOUBLE_EQ(m.recall_20cm_5deg, 0.5);
  EXPECT_TRUE(pose_within(perturbed(5.8, {0.25, 0, 0}), perturbed(0, {0, 0, 0}), loose));
  EXPECT_FALSE(pose_within(perturbed(5.8, {0.25, 0, 0}), perturbed(0, {0, 0, 0}), PoseThresholds{}));
  PoseThresholds bad;
  bad.max_rotation_error_deg = 0.0;
  EXPECT_THROW(evaluate_poses(pose_case(), bad), Error);
}

TEST(EvaluatePoses, NothingLocalized) {
  std::vector<FrameOutcome> frames(3);
  const PoseMetrics m = evaluate_poses(frames);
  EXPECT_EQ(m.num_localized, 0);
  EXPECT_DOUBLE_EQ(m.recall, 0.0);
  EXPECT_TRUE(m.pr_curve.empty());
  EXPECT_DOUBLE_EQ(m.auc, 0.0);
  EXPECT_TRUE(std::isnan(m.median_position_error_m));
  const PoseMetrics empty = evaluate_poses({});
  EXPECT_EQ(empty.num_frames, 0);
  EXPECT_DOUBLE_EQ(empty.auc, 0.0);
}

TEST(EvaluatePoses, EvenCountMedianAndInvalidInput) {
  std::vector<FrameOutcome> frames = {frame(true, perturbed(0, {0.1, 0, 0}), 1, 4, 4),
                                      frame(true, perturbed(0, {0.3, 0, 0}), 2, 4, 4)};
  EXPECT_NEAR(evaluate_poses(frames).median_position_error_m, 0.2, 1e-9);
  frames[0].num_inliers = 5;  // more inliers than correspondences
  EXPECT_THROW(evaluate_poses(frames), Error);
}

// The 7-Scenes convention: recall at 5 cm / 5 deg over all frames, and medians over ALL frames in
// which a frame without a pose is an infinite error.
TEST(EvaluatePoses, SevenScenesRecallAndMediansOverAllFrames) {
  const PoseMetrics m = evaluate_poses(pose_case());
  // Within 5 cm and 5 deg (inclusive): frame 0 (5 cm, 1 deg) and frame 2 (0 cm, 5 deg); frame 4 is
  // 5.001 deg off, frames 1 and 3 20 cm.
  EXPECT_DOUBLE_EQ(m.recall_5cm_5deg, 2.0 / 6.0);
  // Positions {0.05, 0.2, 0, 0.2000001, 0, inf}: the middle two are 0.05 and 0.2; rotations
  // {1, 0, 5, 0, 5.001, inf}: 1 and 5.
  EXPECT_NEAR(m.median_position_error_all_frames_m, 0.125, 1e-9);
  EXPECT_NEAR(m.median_rotation_error_all_frames_deg, 3.0, 1e-9);
  // The medians of the localized frames stay as they were.
  EXPECT_NEAR(m.median_position_error_m, 0.05, 1e-9);

  // Half of the frames without a pose: the middle pair holds an infinite error, the median is inf.
  std::vector<FrameOutcome> half = {frame(true, perturbed(2.0, {0.01, 0, 0}), 10, 10, 10),
                                    frame(true, perturbed(1.0, {0, 0.03, 0}), 10, 10, 10),
                                    frame(false, Rigid3d(), 0, 0, 0), frame(false, Rigid3d(), 0, 0, 0)};
  PoseMetrics h = evaluate_poses(half);
  EXPECT_DOUBLE_EQ(h.recall_5cm_5deg, 0.5);
  EXPECT_TRUE(std::isinf(h.median_position_error_all_frames_m) && h.median_position_error_all_frames_m > 0);
  EXPECT_TRUE(std::isinf(h.median_rotation_error_all_frames_deg));
  EXPECT_NEAR(h.median_position_error_m, 0.02, 1e-9);
  // One more localized frame: the middle of {0.01, 0.03, 0.3, inf, inf} is 0.3 m (at 4 deg).
  half.push_back(frame(true, perturbed(4.0, {0.3, 0, 0}), 10, 10, 10));
  h = evaluate_poses(half);
  EXPECT_NEAR(h.median_position_error_all_frames_m, 0.3, 1e-9);
  EXPECT_NEAR(h.median_rotation_error_all_frames_deg, 4.0, 1e-9);
  EXPECT_DOUBLE_EQ(h.recall_5cm_5deg, 0.4);
  // No frame: NaN.
  EXPECT_TRUE(std::isnan(evaluate_poses({}).median_position_error_all_frames_m));
}

TEST(PoseSweepTest, RecallAndSeedRange) {
  PoseSweep sweep;
  sweep.iterations = {50, 500};
  sweep.seeds = {0, 1, 2};
  sweep.frames_correct = {{1, 3, 2}, {4, 4, 4}};
  sweep.num_frames = 4;
  EXPECT_DOUBLE_EQ(sweep.recall(0, 1), 0.75);
  const SeedRange r = seed_range(sweep, 0);
  EXPECT_DOUBLE_EQ(r.mean, 0.5);
  EXPECT_DOUBLE_EQ(r.min, 0.25);
  EXPECT_DOUBLE_EQ(r.max, 0.75);
  EXPECT_DOUBLE_EQ(seed_range(sweep, 1).min, 1.0);
}

TEST(TrapezoidAuc, KnownArea) {
  EXPECT_DOUBLE_EQ(trapezoid_auc({{0, 0.0, 1.0}, {0, 1.0, 0.0}}), 0.5);
  EXPECT_DOUBLE_EQ(trapezoid_auc({{0, 0.0, 1.0}}), 0.0);
}

}  // namespace
}  // namespace lmb
