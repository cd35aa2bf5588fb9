// Evaluation metrics of `lboost eval` (definitions of the report's fields, docs/report.md):
// landmark retrieval quality of the rankings (precision@1, MRR, the Caltech-style miss rate vs
// false positives per query), the accepted matches (match precision and recall, background
// rejection) and pose quality (errors, recall within thresholds, default 20 cm / 5 deg, a
// precision-recall curve with its AUC, inlier ratio, recall over RANSAC seeds and budgets). Pure
// functions of the per-keypoint rankings and matches and the per-frame pose outcomes; no I/O.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/rigid3.h"
#include "common/types.h"
#include "infer/pose_confidence.h"

namespace lmb {

// One retrieved landmark of a query keypoint. score: higher is better (a classifier score, or
// minus a descriptor distance); informational only, the metrics use the list order.
struct RankedCandidate {
  landmark_t landmark = kInvalidLandmarkId;
  double score = 0.0;
};

// A query keypoint's ranked candidates (best first, distinct landmarks; empty = rejected as
// background) and its true landmark (kInvalidLandmarkId = background, no true landmark).
struct KeypointRanking {
  std::vector<RankedCandidate> candidates;
  landmark_t truth = kInvalidLandmarkId;
};

// One point of the miss-rate curve: retrieving the top `n` candidates of every keypoint with truth.
struct MissRatePoint {
  int n = 0;
  double fppi = 0.0;       // mean false positives per query keypoint with truth
  double miss_rate = 1.0;  // fraction of keypoints with truth whose true landmark is not in the top n
};

// Retrieval metrics over a set of query keypoints.
//
// precision_at_1 and mrr are over the keypoints WITH a true landmark: rank r (1-based) of the true
// landmark in the list, reciprocal rank 1/r, 0 when absent (also when the list is empty).
//
// Miss rate vs false positives per query (FPPI), after Dollar et al. (Caltech pedestrians), with
// rank depth as the operating parameter: for n = 0..N (N = the longest candidate list), every
// keypoint with truth returns its top min(n, list length) candidates. A miss: its true landmark is
// not among them. Its false positives: the returned candidates that are not its true landmark.
// miss_rate(n) = misses / keypoints with truth; fppi(n) = false positives / keypoints with truth.
// Point n = 0 is (fppi 0, miss rate 1). fppi is non-decreasing and miss_rate non-increasing in n.
// Background keypoints do not enter this curve (background rejection: MatchMetrics below).
//
// miss_rate_at(r) for a reference FPPI r > 0: let n be the largest point with fppi(n) <= r.
//   - If n == N (the curve ends at or below r): miss_rate(N) (more candidates do not exist).
//   - Else, if fppi(n) > 0: linear interpolation of the miss rate in log10(fppi) between point n
//     and the next point with a larger fppi.
//   - Else (fppi(n) == 0, which has no log position): miss_rate(n), Dollar's conservative step.
// log_average_miss_rate: Dollar's summary, the geometric mean of miss_rate_at(r) at the nine
// reference FPPIs 10^-2, 10^-1.75, ..., 10^0 (each clamped below at 1e-10).
struct RetrievalMetrics {
  int64_t num_keypoints = 0;
  int64_t num_with_truth = 0;
  double precision_at_1 = 0.0;
  double mrr = 0.0;
  std::vector<MissRatePoint> miss_rate_curve;  // points n = 0..N
  double miss_rate_at_fppi_0_1 = 1.0;
  double miss_rate_at_fppi_1 = 1.0;
  double miss_rate_at_fppi_10 = 1.0;
  double log_average_miss_rate = 1.0;
};

// Computes every retrieval metric. Throws lmb::Error when a candidate list repeats a landmark or
// holds kInvalidLandmarkId. With no keypoint with truth, precision_at_1 = mrr = 0 and the curve
// is the single point (0, 1). Background keypoints count in num_keypoints only.
RetrievalMetrics evaluate_retrieval(const std::vector<KeypointRanking>& rankings);

// ---------------------------------------------------------------------------------------------
// Accepted matches: what a method keeps after its own rejection (LandmarkBoost's background
// margin, a ratio test) and gives to the pose estimator, at most one landmark a keypoint.

// A query keypoint's accepted match (kInvalidLandmarkId = rejected) and its true landmark
// (kInvalidLandmarkId = background).
struct KeypointMatch {
  landmark_t accepted = kInvalidLandmarkId;
  landmark_t truth = kInvalidLandmarkId;
};

// match_precision: accepted matches that are the keypoint's true landmark / accepted matches (a
//   background keypoint's accepted match is always wrong); 0 when nothing is accepted.
// match_recall: keypoints with truth whose accepted match is their true landmark / keypoints with
//   truth; 0 when no keypoint has truth. Without rejection it equals precision_at_1 of the same
//   ranking (the accepted match is the top-ranked landmark).
// background_rejection_rate: background keypoints without an accepted match / background
//   keypoints; 0 when there is no background keypoint.
struct MatchMetrics {
  int64_t num_keypoints = 0;
  int64_t num_with_truth = 0;
  int64_t num_background = 0;
  int64_t num_accepted = 0;
  int64_t num_accepted_correct = 0;
  double match_precision = 0.0;
  double match_recall = 0.0;
  double background_rejection_rate = 0.0;
};

MatchMetrics evaluate_matches(const std::vector<KeypointMatch>& matches);

// The miss rate at a reference FPPI r > 0 on a curve from evaluate_retrieval (definition above).
// Throws lmb::Error on an empty curve or r <= 0.
double miss_rate_at_fppi(const std::vector<MissRatePoint>& curve, double fppi);

// ---------------------------------------------------------------------------------------------
// Pose quality.

// What a method produced for one query frame.
struct FrameOutcome {
  bool localized = false;       // the pose estimator reported success
  Rigid3d cam_from_world;       // the estimate; meaningful only when localized
  Rigid3d true_cam_from_world;  // ground truth
  double confidence = 0.0;      // higher = more trusted, e.g. the inlier count; swept for the PR curve
  int num_correspondences = 0;  // 2D-3D matches fed to PnP + RANSAC
  int num_inliers = 0;          // inliers of the returned pose (ignored when not localized)
  double match_ms = 0.0;        // matching / classification time of the frame, milliseconds
  double total_ms = 0.0;        // matching + pose estimation time of the frame, milliseconds
  PoseEvidence evidence;        // what the pose's calibrated confidence reads (infer/pose_confidence.h)
};

struct PoseThresholds {
  double max_position_error_m = 0.20;
  double max_rotation_error_deg = 5.0;
  void check() const;  // throws lmb::Error unless both are finite and > 0
};

// Parses "METRES,DEGREES[;METRES,DEGREES...]" (e.g. "0.2,5;1,2;0.05,1"). Throws lmb::Error naming
// `what` (e.g. "eval: --pose-thresholds") on anything else, an empty list or a non-positive value.
std::vector<PoseThresholds> parse_pose_thresholds(const std::string& text, const std::string& what);

// Whether an estimate is within the thresholds of the truth (the rule below, slack included).
bool pose_within(const Rigid3d& cam_from_world, const Rigid3d& true_cam_from_world, const PoseThresholds& thresholds);

// One point of the pose precision-recall curve: frames accepted when localized and
// confidence >= threshold.
struct PosePrPoint {
  double threshold = 0.0;
  double recall = 0.0;     // correct accepted frames / ALL query frames
  double precision = 0.0;  // correct accepted frames / accepted frames
};

// Per-frame errors and the summary over all query frames.
//
// A frame is correct when localized, position error <= max_position_error_m and rotation error
// <= max_rotation_error_deg. Both comparisons are inclusive with a relative slack of 1e-9 so that a
// pose built exactly at the threshold (e.g. a 5-degree AngleAxis) counts despite rounding.
// Position error: distance between camera centres (world units, metres); rotation error: the angle
// of the relative rotation in degrees (common/rigid3.h).
//
// Precision-recall: the thresholds are the distinct confidences of the localized frames, from the
// highest down (frames of equal confidence enter together). The curve starts with an anchor point
// at recall 0 whose precision is that of the first (highest-threshold) point, i.e. the curve is
// extended flat to zero recall. AUC: trapezoid rule over recall along the curve from that anchor;
// at most the final recall. No localized frame: empty curve, AUC 0.
//
// Medians are over localized frames (NaN when none; the mean of the middle two for an even count).
// The 7-Scenes convention beside them: recall_5cm_5deg (frames localized within 5 cm and 5 deg /
// ALL query frames) and the medians over ALL query frames, where a frame without a pose counts as
// an infinite error (so the median is infinite when half of the frames or more are not localized;
// NaN when there is no frame).
// Inlier ratio of a frame: num_inliers / num_correspondences when localized with at least one
// correspondence, else 0; mean_inlier_ratio is over ALL query frames.
struct PoseMetrics {
  int64_t num_frames = 0;
  int64_t num_localized = 0;
  int64_t num_correct = 0;
  std::vector<double> position_error_m;    // per frame; NaN when not localized
  std::vector<double> rotation_error_deg;  // per frame; NaN when not localized
  std::vector<double> inlier_ratio;        // per frame (see above)
  std::vector<char> correct;               // per frame: 1 when correct
  double recall = 0.0;                     // num_correct / num_frames (0 when no frame)
  double recall_20cm_5deg = 0.0;           // the same at 20 cm / 5 deg, whatever the thresholds
  double recall_5cm_5deg = 0.0;            // the same at 5 cm / 5 deg (7-Scenes)
  std::vector<PosePrPoint> pr_curve;       // anchor first, then by decreasing threshold
  double auc = 0.0;
  double median_position_error_m = 0.0;
  double median_rotation_error_deg = 0.0;
  double median_position_error_all_frames_m = 0.0;    // over all frames, not localized = infinite
  double median_rotation_error_all_frames_deg = 0.0;  // likewise
  double mean_inlier_ratio = 0.0;
  double mean_match_ms = 0.0;  // over all frames (0 when no frame)
  double mean_total_ms = 0.0;
};

// Throws lmb::Error on invalid thresholds, num_inliers > num_correspondences or negative counts,
// or a non-finite confidence of a localized frame.
PoseMetrics evaluate_poses(const std::vector<FrameOutcome>& frames,
                           const PoseThresholds& thresholds = PoseThresholds());

// The area under a precision-recall curve by the trapezoid rule over recall (points in order of
// non-decreasing recall). Exposed for tests and other curves.
double trapezoid_auc(const std::vector<PosePrPoint>& curve);

// Pose recall at several RANSAC iteration budgets and seeds (the same correspondences, one
// RANSAC run per budget and seed): how much of a method's recall is the luck of one seed.
struct PoseSweep {
  std::vector<int> iterations;  // budgets
  std::vector<uint64_t> seeds;
  std::vector<std::vector<int64_t>> frames_correct;  // [budget][seed]
  // The same frames' success: reported by the inlier rule (at least min_inliers inliers), and by the
  // calibrated rule (that and the calibrated probability at least its threshold) with how many of
  // those are correct; [budget][seed], the calibrated ones empty when the sweep has no calibration.
  std::vector<std::vector<int64_t>> frames_localized;
  std::vector<std::vector<int64_t>> calibrated_localized;
  std::vector<std::vector<int64_t>> calibrated_correct;
  int64_t num_frames = 0;
  // Recall of budget b, seed s: frames_correct[b][s] / num_frames (0 when no frame).
  double recall(size_t b, size_t s) const;
};

// Summary over the seeds of one budget.
struct SeedRange {
  double mean = 0.0, min = 0.0, max = 0.0;
};
SeedRange seed_range(const PoseSweep& sweep, size_t budget);

}  // namespace lmb
