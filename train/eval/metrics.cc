#include "train/eval/metrics.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

#include "common/error.h"
#include "common/stats.h"

namespace lmb {

namespace {

// Lists are short (tens of candidates): a quadratic duplicate check is cheapest.
void check_candidates(const KeypointRanking& r, size_t index) {
  const auto& c = r.candidates;
  for (size_t i = 0; i < c.size(); ++i) {
    LMB_CHECK(c[i].landmark != kInvalidLandmarkId,
              "evaluate_retrieval: keypoint " << index << " candidate " << i << " is kInvalidLandmarkId");
    for (size_t j = 0; j < i; ++j) {
      LMB_CHECK(c[i].landmark != c[j].landmark, "evaluate_retrieval: keypoint " << index << " lists landmark "
                                                                                << c[i].landmark << " twice (ranks "
                                                                                << j + 1 << " and " << i + 1 << ")");
    }
  }
}

bool within(double value, double limit) { return value <= limit * (1.0 + 1e-9); }

}  // namespace

double miss_rate_at_fppi(const std::vector<MissRatePoint>& curve, double fppi) {
  LMB_CHECK(!curve.empty(), "miss_rate_at_fppi: empty curve");
  LMB_CHECK(fppi > 0.0 && std::isfinite(fppi), "miss_rate_at_fppi: reference FPPI " << fppi << " is not > 0");
  // Largest n with fppi(n) <= r (fppi is non-decreasing).
  size_t n = 0;
  bool found = false;
  for (size_t i = 0; i < curve.size(); ++i) {
    if (curve[i].fppi <= fppi) {
      n = i;
      found = true;
    }
  }
  if (!found) return 1.0;  // cannot happen with a point (0, 1) first; be safe for hand-made curves
  if (n + 1 == curve.size()) return curve[n].miss_rate;
  const MissRatePoint& a = curve[n];
  if (a.fppi <= 0.0) return a.miss_rate;
  // The next point with a larger fppi: n + 1, since n is the largest with fppi <= r.
  const MissRatePoint& b = curve[n + 1];
  const double t = (std::log10(fppi) - std::log10(a.fppi)) / (std::log10(b.fppi) - std::log10(a.fppi));
  return a.miss_rate + t * (b.miss_rate - a.miss_rate);
}

RetrievalMetrics evaluate_retrieval(const std::vector<KeypointRanking>& rankings) {
  RetrievalMetrics m;
  m.num_keypoints = static_cast<int64_t>(rankings.size());
  size_t max_len = 0;
  // hits_at_rank[r]: keypoints with truth whose true landmark is at rank r (1-based).
  std::vector<int64_t> hits_at_rank(1, 0);
  // ended_at[l]: keypoints with truth whose list has length l (bounds the false positives).
  std::vector<int64_t> ended_at(1, 0);
  double p1_sum = 0.0;
  double rr_sum = 0.0;
  for (size_t i = 0; i < rankings.size(); ++i) {
    const KeypointRanking& r = rankings[i];
    check_candidates(r, i);
    const size_t len = r.candidates.size();
    if (r.truth == kInvalidLandmarkId) continue;
    ++m.num_with_truth;
    max_len = std::max(max_len, len);
    if (ended_at.size() <= len) ended_at.resize(len + 1, 0);
    ++ended_at[len];
    for (size_t k = 0; k < len; ++k) {
      if (r.candidates[k].landmark == r.truth) {
        if (hits_at_rank.size() <= k + 1) hits_at_rank.resize(k + 2, 0);
        ++hits_at_rank[k + 1];
        if (k == 0) p1_sum += 1.0;
        rr_sum += 1.0 / static_cast<double>(k + 1);
        break;
      }
    }
  }

  m.miss_rate_curve.push_back(MissRatePoint{0, 0.0, 1.0});
  if (m.num_with_truth > 0) {
    const double count = static_cast<double>(m.num_with_truth);
    m.precision_at_1 = p1_sum / count;
    m.mrr = rr_sum / count;
    hits_at_rank.resize(max_len + 1, 0);
    ended_at.resize(max_len + 1, 0);
    // Walking n up: returned(n) = sum over keypoints of min(n, len); hits(n) = true landmark at rank <= n.
    int64_t hits = 0;
    int64_t returned = 0;
    int64_t still_long = m.num_with_truth;  // keypoints with len >= n
    for (size_t n = 1; n <= max_len; ++n) {
      still_long -= ended_at[n - 1];
      returned += still_long;
      hits += hits_at_rank[n];
      const double fp = static_cast<double>(returned - hits);
      m.miss_rate_curve.push_back(
          MissRatePoint{static_cast<int>(n), fp / count, 1.0 - static_cast<double>(hits) / count});
    }
  }
  m.miss_rate_at_fppi_0_1 = miss_rate_at_fppi(m.miss_rate_curve, 0.1);
  m.miss_rate_at_fppi_1 = miss_rate_at_fppi(m.miss_rate_curve, 1.0);
  m.miss_rate_at_fppi_10 = miss_rate_at_fppi(m.miss_rate_curve, 10.0);
  double log_sum = 0.0;
  for (int i = 0; i < 9; ++i) {
    const double ref = std::pow(10.0, -2.0 + 0.25 * i);
    log_sum += std::log(std::max(1e-10, miss_rate_at_fppi(m.miss_rate_curve, ref)));
  }
  m.log_average_miss_rate = std::exp(log_sum / 9.0);
  return m;
}

MatchMetrics evaluate_matches(const std::vector<KeypointMatch>& matches) {
  MatchMetrics m;
  m.num_keypoints = static_cast<int64_t>(matches.size());
  int64_t background_rejected = 0;
  for (const KeypointMatch& k : matches) {
    const bool accepted = k.accepted != kInvalidLandmarkId;
    const bool correct = accepted && k.accepted == k.truth;
    m.num_accepted += accepted;
    m.num_accepted_correct += correct;
    if (k.truth == kInvalidLandmarkId) {
      ++m.num_background;
      background_rejected += !accepted;
    } else {
      ++m.num_with_truth;
    }
  }
  const auto ratio = [](int64_t a, int64_t b) { return b > 0 ? static_cast<double>(a) / static_cast<double>(b) : 0.0; };
  m.match_precision = ratio(m.num_accepted_correct, m.num_accepted);
  m.match_recall = ratio(m.num_accepted_correct, m.num_with_truth);
  m.background_rejection_rate = ratio(background_rejected, m.num_background);
  return m;
}

void PoseThresholds::check() const {
  LMB_CHECK(std::isfinite(max_position_error_m) && max_position_error_m > 0.0,
            "PoseThresholds: max_position_error_m " << max_position_error_m << " must be finite and > 0");
  LMB_CHECK(std::isfinite(max_rotation_error_deg) && max_rotation_error_deg > 0.0,
            "PoseThresholds: max_rotation_error_deg " << max_rotation_error_deg << " must be finite and > 0");
}

std::vector<PoseThresholds> parse_pose_thresholds(const std::string& text, const std::string& what) {
  std::vector<PoseThresholds> out;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = std::min(text.find(';', start), text.size());
    const std::string pair = text.substr(start, end - start);
    const size_t comma = pair.find(',');
    PoseThresholds t;
    bool ok = comma != std::string::npos;
    if (ok) {
      char* rest = nullptr;
      const std::string metres = pair.substr(0, comma), degrees = pair.substr(comma + 1);
      t.max_position_error_m = std::strtod(metres.c_str(), &rest);
      ok = !metres.empty() && *rest == '\0';
      t.max_rotation_error_deg = std::strtod(degrees.c_str(), &rest);
      ok = ok && !degrees.empty() && *rest == '\0';
    }
    LMB_CHECK(ok, what << " '" << text << "': '" << pair
                       << "' is not METRES,DEGREES (pairs separated by ';', e.g. 0.2,5;1,2)");
    LMB_CHECK(std::isfinite(t.max_position_error_m) && t.max_position_error_m > 0 &&
                  std::isfinite(t.max_rotation_error_deg) && t.max_rotation_error_deg > 0,
              what << " '" << text << "': '" << pair << "': both thresholds must be finite and > 0");
    out.push_back(t);
    start = end + 1;
  }
  return out;
}

bool pose_within(const Rigid3d& cam_from_world, const Rigid3d& true_cam_from_world, const PoseThresholds& thresholds) {
  return within(position_error(cam_from_world, true_cam_from_world), thresholds.max_position_error_m) &&
         within(rotation_error_deg(cam_from_world, true_cam_from_world), thresholds.max_rotation_error_deg);
}

double PoseSweep::recall(size_t b, size_t s) const {
  return num_frames > 0 ? static_cast<double>(frames_correct[b][s]) / static_cast<double>(num_frames) : 0.0;
}

SeedRange seed_range(const PoseSweep& sweep, size_t budget) {
  SeedRange r;
  const size_t n = sweep.seeds.size();
  if (n == 0) return r;
  r.min = r.max = sweep.recall(budget, 0);
  for (size_t s = 0; s < n; ++s) {
    const double v = sweep.recall(budget, s);
    r.mean += v;
    r.min = std::min(r.min, v);
    r.max = std::max(r.max, v);
  }
  r.mean /= static_cast<double>(n);
  return r;
}

double trapezoid_auc(const std::vector<PosePrPoint>& curve) {
  double auc = 0.0;
  for (size_t i = 1; i < curve.size(); ++i) {
    auc += (curve[i].recall - curve[i - 1].recall) * 0.5 * (curve[i].precision + curve[i - 1].precision);
  }
  return auc;
}

PoseMetrics evaluate_poses(const std::vector<FrameOutcome>& frames, const PoseThresholds& thresholds) {
  thresholds.check();
  PoseMetrics m;
  const size_t n = frames.size();
  m.num_frames = static_cast<int64_t>(n);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  m.position_error_m.assign(n, nan);
  m.rotation_error_deg.assign(n, nan);
  m.inlier_ratio.assign(n, 0.0);
  m.correct.assign(n, 0);
  std::vector<double> pos_localized, rot_localized;
  // Every frame's errors, infinite when not localized (the 7-Scenes medians).
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> pos_all(n, inf), rot_all(n, inf);
  double ratio_sum = 0.0, match_sum = 0.0, total_sum = 0.0;
  int64_t correct_20cm_5deg = 0, correct_5cm_5deg = 0;
  for (size_t i = 0; i < n; ++i) {
    const FrameOutcome& f = frames[i];
    LMB_CHECK(f.num_correspondences >= 0 && f.num_inliers >= 0,
              "evaluate_poses: frame " << i << " has a negative correspondence or inlier count");
    match_sum += f.match_ms;
    total_sum += f.total_ms;
    if (!f.localized) continue;
    LMB_CHECK(f.num_inliers <= f.num_correspondences, "evaluate_poses: frame "
                                                          << i << " has " << f.num_inliers << " inliers but only "
                                                          << f.num_correspondences << " correspondences");
    LMB_CHECK(std::isfinite(f.confidence), "evaluate_poses: frame " << i << " has a non-finite confidence");
    ++m.num_localized;
    const double pe = position_error(f.cam_from_world, f.true_cam_from_world);
    const double re = rotation_error_deg(f.cam_from_world, f.true_cam_from_world);
    m.position_error_m[i] = pe;
    m.rotation_error_deg[i] = re;
    pos_localized.push_back(pe);
    rot_localized.push_back(re);
    pos_all[i] = pe;
    rot_all[i] = re;
    if (f.num_correspondences > 0) {
      m.inlier_ratio[i] = static_cast<double>(f.num_inliers) / static_cast<double>(f.num_correspondences);
    }
    ratio_sum += m.inlier_ratio[i];
    if (within(pe, thresholds.max_position_error_m) && within(re, thresholds.max_rotation_error_deg)) {
      m.correct[i] = 1;
      ++m.num_correct;
    }
    correct_20cm_5deg += within(pe, 0.20) && within(re, 5.0);
    correct_5cm_5deg += within(pe, 0.05) && within(re, 5.0);
  }
  if (n > 0) {
    const double count = static_cast<double>(n);
    m.recall = static_cast<double>(m.num_correct) / count;
    m.recall_20cm_5deg = static_cast<double>(correct_20cm_5deg) / count;
    m.recall_5cm_5deg = static_cast<double>(correct_5cm_5deg) / count;
    m.mean_inlier_ratio = ratio_sum / count;
    m.mean_match_ms = match_sum / count;
    m.mean_total_ms = total_sum / count;
  }
  m.median_position_error_m = median(pos_localized);
  m.median_rotation_error_deg = median(rot_localized);
  m.median_position_error_all_frames_m = median(pos_all);
  m.median_rotation_error_all_frames_deg = median(rot_all);

  // Precision-recall by sweeping the confidence threshold from the top.
  std::vector<size_t> order;
  for (size_t i = 0; i < n; ++i) {
    if (frames[i].localized) order.push_back(i);
  }
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return frames[a].confidence > frames[b].confidence; });
  int64_t accepted = 0, correct = 0;
  for (size_t k = 0; k < order.size();) {
    const double threshold = frames[order[k]].confidence;
    while (k < order.size() && frames[order[k]].confidence == threshold) {
      ++accepted;
      correct += m.correct[order[k]];
      ++k;
    }
    PosePrPoint p;
    p.threshold = threshold;
    p.recall = static_cast<double>(correct) / static_cast<double>(n);
    p.precision = static_cast<double>(correct) / static_cast<double>(accepted);
    if (m.pr_curve.empty()) {
      PosePrPoint anchor = p;
      anchor.recall = 0.0;
      m.pr_curve.push_back(anchor);
    }
    m.pr_curve.push_back(p);
  }
  m.auc = trapezoid_auc(m.pr_curve);
  return m;
}

}  // namespace lmb
