#include "infer/detail/scoring_index.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/hamming.h"

namespace lmb::detail {

ScoringIndex::ScoringIndex(const ModelData& data) : layout_(layout_of(data)) {
  const int32_t C = data.num_classes;
  const size_t M = data.stumps.size();

  for (const SharedStump& s : data.stumps) used_dims_.push_back(s.dim);
  std::sort(used_dims_.begin(), used_dims_.end());
  used_dims_.erase(std::unique(used_dims_.begin(), used_dims_.end()), used_dims_.end());

  dense_stumps_.resize(M);
  stump_class_begin_.assign(M + 1, 0);
  std::vector<int64_t> class_count(static_cast<size_t>(C) + 1, 0);
  for (size_t m = 0; m < M; ++m) {
    const SharedStump& s = data.stumps[m];
    DenseStump& d = dense_stumps_[m];
    d.used = static_cast<int32_t>(std::lower_bound(used_dims_.begin(), used_dims_.end(), s.dim) - used_dims_.begin());
    d.theta = s.theta;
    d.above = s.a + s.b;  // BoostModel: (fires ? a : 0.0) + b, the same double
    d.below = s.b;
    stump_class_begin_[m + 1] = stump_class_begin_[m] + static_cast<int64_t>(s.classes.size());
    stump_classes_.insert(stump_classes_.end(), s.classes.begin(), s.classes.end());
    for (int32_t c : s.classes) ++class_count[c];
  }

  class_stump_begin_.assign(static_cast<size_t>(C) + 2, 0);
  for (int32_t c = 0; c <= C; ++c) class_stump_begin_[c + 1] = class_stump_begin_[c] + class_count[c];
  class_stumps_.resize(static_cast<size_t>(class_stump_begin_[C + 1]));
  class_stump_index_.resize(class_stumps_.size());
  std::vector<int64_t> fill(class_stump_begin_.begin(), class_stump_begin_.end() - 1);
  for (size_t m = 0; m < M; ++m) {
    for (int32_t c : data.stumps[m].classes) {
      class_stump_index_[fill[c]] = static_cast<int32_t>(m);
      class_stumps_[fill[c]++] = dense_stumps_[m];
    }
  }

  const int32_t W = data.vocabulary.num_words();
  word_class_begin_.assign(static_cast<size_t>(W) + 1, 0);
  word_used_begin_.assign(static_cast<size_t>(W) + 1, 0);
  std::vector<uint8_t> mark(used_dims_.size());
  for (int32_t w = 0; w < W; ++w) {
    const std::vector<int32_t>& list = data.inverted_file[w];
    word_classes_.insert(word_classes_.end(), list.begin(), list.end());
    word_class_begin_[w + 1] = static_cast<int32_t>(word_classes_.size());
    std::fill(mark.begin(), mark.end(), 0);
    auto mark_class = [&](int32_t c) {
      for (int64_t e = class_stump_begin_[c]; e < class_stump_begin_[c + 1]; ++e) {
        mark[class_stumps_[e].used] = 1;
      }
    };
    for (int32_t c : list) mark_class(c);
    mark_class(C);  // the background is always scored
    for (size_t u = 0; u < mark.size(); ++u) {
      if (mark[u]) {
        word_used_.push_back(static_cast<int32_t>(u));
        word_used_dims_.push_back(used_dims_[u]);
      }
    }
    word_used_begin_[w + 1] = static_cast<int32_t>(word_used_.size());
    word_plans_.emplace_back(
        data.regions, layout_,
        std::vector<int32_t>(word_used_dims_.begin() + word_used_begin_[w], word_used_dims_.end()));
  }
  used_plan_ = DimPlan(data.regions, layout_, used_dims_);
  if (data.fusion.enabled()) build_fusion_balls(data);
  build_screen(data);
}

void ScoringIndex::build_fusion_balls(const ModelData& data) {
  const DescriptorFusion& f = data.fusion;
  const int32_t bytes = data.descriptor_bytes;
  const std::vector<double>& score = f.distance_score;
  fusion_term_bound_.assign(score.size(), 0.0);
  double best = -std::numeric_limits<double>::infinity();
  for (size_t d = score.size(); d-- > 0;) fusion_term_bound_[d] = best = std::max(best, score[d]);
  const int32_t C = data.num_classes;
  fusion_ball_begin_.assign(static_cast<size_t>(C) + 1, 0);
  std::vector<int32_t> nearest, owner;
  for (int32_t c = 0; c < C; ++c) {
    const int64_t first = f.exemplar_begin[c], n = f.exemplar_begin[c + 1] - first;
    fusion_ball_begin_[c + 1] = fusion_ball_begin_[c];
    if (n < kMinBallExemplars) continue;
    const auto balls = static_cast<int64_t>(std::ceil(std::sqrt(2.0 * static_cast<double>(n))));
    const uint8_t* rows = f.exemplars.data() + first * bytes;
    nearest.assign(static_cast<size_t>(n), std::numeric_limits<int32_t>::max());
    owner.assign(static_cast<size_t>(n), 0);
    const auto ball0 = static_cast<int32_t>(fusion_ball_radius_.size());
    int64_t next = 0;  // the first centre: the class's first exemplar; then the farthest from the centres
    for (int32_t b = 0; b < balls; ++b) {
      fusion_ball_centres_.insert(fusion_ball_centres_.end(), rows + next * bytes, rows + (next + 1) * bytes);
      fusion_ball_radius_.push_back(0);
      const uint8_t* centre = rows + next * bytes;
      int64_t farthest = 0;
      for (int64_t i = 0; i < n; ++i) {
        const int32_t d = hamming_distance(rows + i * bytes, centre, bytes);
        if (d < nearest[i]) {
          nearest[i] = d;
          owner[i] = b;
        }
        if (nearest[i] > nearest[farthest]) farthest = i;
      }
      next = farthest;
    }
    for (int64_t i = 0; i < n; ++i) {
      int32_t& radius = fusion_ball_radius_[static_cast<size_t>(ball0 + owner[i])];
      radius = std::max(radius, nearest[i]);
    }
    fusion_ball_begin_[c + 1] += balls;
  }
}

bool fusion_term_bounds(const Model& model, int32_t cls, const uint8_t* descriptors, uint32_t lanes, int32_t* distance,
                        double* out) {
  const ScoringIndex& idx = model.scoring();
  const int64_t begin = idx.fusion_ball_begin()[cls], end = idx.fusion_ball_begin()[cls + 1];
  if (begin == end) return false;
  const int32_t bytes = model.descriptor_bytes();
  hamming_ball_low_lanes(descriptors, lanes, idx.fusion_ball_centres().data() + begin * bytes,
                         idx.fusion_ball_radius().data() + begin, end - begin, bytes, distance);
  for (; lanes != 0; lanes &= lanes - 1) {
    const int j = __builtin_ctz(lanes);
    out[j] = idx.fusion_term_bound()[distance[j]];
  }
  return true;
}

double fusion_term(const Model& model, int32_t cls, const uint8_t* descriptor) {
  const ModelData& data = model.data();
  if (!data.fusion.enabled()) return 0.0;
  const DescriptorFusion& f = data.fusion;
  const int32_t bytes = data.descriptor_bytes;
  const int64_t first = f.exemplar_begin[cls];
  const int d = hamming_min(descriptor, f.exemplars.data() + first * bytes, f.exemplar_begin[cls + 1] - first, bytes);
  return f.distance_score[d];
}

void fusion_terms(const Model& model, int32_t cls, const uint8_t* descriptors, uint32_t lanes, int32_t* distance,
                  double* out) {
  const ModelData& data = model.data();
  const DescriptorFusion& f = data.fusion;
  const int32_t bytes = data.descriptor_bytes;
  const int64_t first = f.exemplar_begin[cls];
  hamming_min_lanes(descriptors, lanes, f.exemplars.data() + first * bytes, f.exemplar_begin[cls + 1] - first, bytes,
                    distance);
  for (; lanes != 0; lanes &= lanes - 1) {
    const int j = __builtin_ctz(lanes);
    out[j] = f.distance_score[distance[j]];
  }
}

// Why offset_c + step * x bounds the exact score F of class c from above, x = t at the end, or
// t_k + add_ck at checkpoint k (u = 2^-53, n = the class's stumps, h_i = above_i or below_i its
// outputs in training order):
//   F is the chain F_0 = bias, F_i = fl(F_{i-1} + h_i); every |F_i| <= G (1 + u)^n with
//   G = |bias| + sum (|above_i| + |below_i|), so F <= S + 2 n u G, S the exact real sum.
//   S = bias + sum below_i + sum fires_i (step q_i + r_i), r_i = above_i - below_i - step q_i
//     <= bias + sum below_i + sum max(0, r_i) + step Q, and Q = low + t; at checkpoint k,
//   Q <= Q_k + (the positive q of the remaining stumps) = low + t_k + add_ck.
//   offset_c is bias + sum below_i + sum max(0, r_i) + step low computed in doubles (n + 3 terms,
//   each within 3u of its real value relative to its magnitude) plus a slack; the run-time sum
//   offset + step x (x < 2^17, step x exact) rounds once more. Every error is at most
//   (4 n + 16) u H with H = G + sum (|below_i| + 2 step |q_i| + max(0, r_i)) + step 2^17 +
//   |offset terms| (`magnitude`), so the slack 2 (8 n + 32) u H covers them with room (H is a sum
//   of non-negative doubles, within (n + 8) u of exact).
void ScoringIndex::build_screen(const ModelData& data) {
  const int32_t C = data.num_classes;
  const size_t M = dense_stumps_.size();
  std::vector<double> step_of(M);
  double max_class_sum = 0.0;
  for (size_t m = 0; m < M; ++m) step_of[m] = std::fabs(dense_stumps_[m].above - dense_stumps_[m].below);
  for (int32_t c = 0; c < C; ++c) {
    double sum = 0.0;
    for (int64_t e = class_stump_begin_[c]; e < class_stump_begin_[c + 1]; ++e) {
      sum += step_of[class_stump_index_[e]];
    }
    max_class_sum = std::max(max_class_sum, sum);
  }
  // The smallest power of two with every |q_m| <= 32767 and every class's sum of |q| <= 65535
  // (all q = 0 when the steps overflow: then every bound is +inf and nothing is skipped).
  int exponent = -1000;
  if (max_class_sum > 0.0) exponent = std::max(exponent, std::ilogb(max_class_sum / 65000.0));
  std::vector<int64_t> q(M, 0);
  for (; std::isfinite(max_class_sum) && exponent <= 1023; ++exponent) {
    const double step = std::ldexp(1.0, exponent);
    bool fits = true;
    for (size_t m = 0; m < M && fits; ++m) {
      // Only stumps of some landmark class are screened (the background is always scored exactly).
      const std::vector<int32_t>& members = data.stumps[m].classes;
      const double r =
          members.front() < C ? std::nearbyint((dense_stumps_[m].above - dense_stumps_[m].below) / step) : 0.0;
      fits = std::fabs(r) <= 32767.0;
      q[m] = fits ? static_cast<int64_t>(r) : 0;
    }
    for (int32_t c = 0; c < C && fits; ++c) {
      int64_t sum = 0;
      for (int64_t e = class_stump_begin_[c]; e < class_stump_begin_[c + 1]; ++e) {
        sum += std::abs(q[class_stump_index_[e]]);
      }
      fits = sum <= 65535;
    }
    if (fits) break;
  }
  const bool usable = std::isfinite(max_class_sum) && exponent <= 1023 && M <= 65536;
  if (!usable) std::fill(q.begin(), q.end(), 0);
  screen_step_ = usable ? std::ldexp(1.0, exponent) : 1.0;
  screen_q_.assign(q.begin(), q.end());
  screen_offset_.resize(static_cast<size_t>(C));
  screen_units_.resize(static_cast<size_t>(C));
  screen_low_.resize(static_cast<size_t>(C));
  // The screening lists: every class's stumps by decreasing |q| (ties: training order), filled
  // from one global order of the stumps.
  std::vector<int32_t> by_step(M);
  for (size_t m = 0; m < M; ++m) by_step[m] = static_cast<int32_t>(m);
  std::stable_sort(by_step.begin(), by_step.end(),
                   [&](int32_t x, int32_t y) { return std::abs(q[x]) > std::abs(q[y]); });
  std::vector<int32_t> list_of(class_stump_index_.size());
  {
    std::vector<int64_t> fill(class_stump_begin_.begin(), class_stump_begin_.end() - 1);
    for (int32_t m : by_step) {
      for (int32_t c : data.stumps[m].classes) list_of[fill[c]++] = m;
    }
  }
  screen_list_.resize(list_of.size());
  for (size_t e = 0; e < list_of.size(); ++e) screen_list_[e] = usable ? static_cast<uint16_t>(list_of[e]) : 0;
  screen_check_begin_.assign(static_cast<size_t>(C) + 1, 0);
  const double u = std::ldexp(1.0, -53);
  for (int32_t c = 0; c < C; ++c) {
    const int64_t first = class_stump_begin_[c], n = class_stump_begin_[c + 1] - first;
    const double bias = data.bias[c];
    // The run-time multiple of step is below 2 * 65536 (t_k < 2^16, add_ck <= sum of |q| <= 65535).
    double constant = bias, magnitude = std::fabs(bias) + screen_step_ * 131072.0;
    int64_t low = 0, high = 0;
    for (int64_t e = first; e < first + n; ++e) {
      const int32_t m = class_stump_index_[e];
      const DenseStump& st = dense_stumps_[m];
      const double stepped = screen_step_ * static_cast<double>(q[m]);
      const double rest = std::max(0.0, st.above - st.below - stepped);
      constant += st.below + rest;
      magnitude += std::fabs(st.above) + 2.0 * std::fabs(st.below) + 2.0 * std::fabs(stepped) + rest;
      low += std::min<int64_t>(0, q[m]);
      high += std::max<int64_t>(0, q[m]);
    }
    // The checkpoints of the screening list: prefix sums of the negative q, suffix sums of the
    // positive ones.
    const int32_t* list = list_of.data() + first;
    int64_t prefix_low = 0, suffix_high = high;
    for (int64_t k = 1; k * kScreenCheck < n; ++k) {
      for (int64_t i = (k - 1) * kScreenCheck; i < k * kScreenCheck; ++i) {
        prefix_low += std::min<int64_t>(0, q[list[i]]);
        suffix_high -= std::max<int64_t>(0, q[list[i]]);
      }
      screen_check_low_.push_back(static_cast<uint16_t>(prefix_low & 0xFFFF));
      screen_check_add_.push_back(static_cast<int32_t>(prefix_low - low + suffix_high));
    }
    screen_check_begin_[c + 1] = static_cast<int64_t>(screen_check_low_.size());
    const double stepped_low = screen_step_ * static_cast<double>(low);
    constant += stepped_low;
    magnitude += std::fabs(constant) + std::fabs(stepped_low);
    const double slack = 2.0 * static_cast<double>(8 * n + 32) * u * magnitude;
    // A non-finite bound (overflow) is +inf: the class is always scored exactly.
    const double bound = constant + slack;
    screen_offset_[c] = usable && std::isfinite(bound) ? bound : std::numeric_limits<double>::infinity();
    screen_low_[c] = static_cast<uint16_t>(low & 0xFFFF);
    // offset_c in steps, rounded up and clamped (see screen_units() in scoring_index.h; +inf and every
    // offset above the clamp give the largest value, whose test always passes).
    const double units = std::ceil(screen_offset_[c] / screen_step_);
    screen_units_[c] = static_cast<int32_t>(std::clamp(units, -double{kScreenUnitsLimit}, double{kScreenUnitsLimit}));
  }
}

}  // namespace lmb::detail
