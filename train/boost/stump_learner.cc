#include "train/boost/stump_learner.h"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>

#include <emmintrin.h>
#include <limits>
#include <numeric>
#include <tuple>

#include "common/cpu_dispatch.h"
#include "common/error.h"
#include "common/random.h"

namespace lmb {

namespace {

constexpr uint64_t kDrawTag = 0x4452415744494D53ull;      // dims of F_m
constexpr uint64_t kNegativeTag = 0x4E45474154495645ull;  // bootstrapped negatives
constexpr uint64_t kValidationTag = 0x56414C4944415445ull;
constexpr uint64_t kPoolTag = 0x504F4F4C53414D50ull;

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Uniform index in [0, n) from 64 random bits.
inline uint64_t scale_to(uint64_t bits, uint64_t n) {
  __extension__ typedef unsigned __int128 u128;
  return static_cast<uint64_t>((static_cast<u128>(bits) * n) >> 64);
}

// (alpha, beta) = (a + b, b) of a set's sums; the other side's value when one side is empty.
void fit_alpha_beta(const StumpRecord& r, double* alpha, double* beta) {
  const bool has_p = r.wp > 0, has_m = r.wm > 0;
  const double a = has_p ? static_cast<double>(r.yp) / static_cast<double>(r.wp) : 0.0;
  const double b = has_m ? static_cast<double>(r.ym) / static_cast<double>(r.wm) : 0.0;
  *alpha = has_p ? a : b;
  *beta = has_m ? b : a;
}

// Samples chosen by a seeded hash order, at most `cap`, returned ascending.
std::vector<int64_t> hash_subset(const std::vector<int64_t>& samples, int64_t cap, uint64_t seed, uint64_t tag) {
  if (static_cast<int64_t>(samples.size()) <= cap) return samples;
  std::vector<std::pair<uint64_t, int64_t>> keyed;
  keyed.reserve(samples.size());
  for (int64_t s : samples) keyed.emplace_back(counter_hash(seed, tag, static_cast<uint64_t>(s)), s);
  std::nth_element(keyed.begin(), keyed.begin() + cap, keyed.end());
  std::vector<int64_t> out;
  for (int64_t i = 0; i < cap; ++i) out.push_back(keyed[i].second);
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

bool stump_better(const StumpRecord& x, const StumpRecord& y) {
  if (x.valid() != y.valid()) return x.valid();
  if (x.gain != y.gain) return x.gain > y.gain;
  if (x.dim != y.dim) return x.dim < y.dim;
  return x.theta < y.theta;
}

std::vector<int32_t> draw_round_dims(uint64_t seed, int32_t round, int32_t num_dims, int32_t k) {
  LMB_CHECK(k >= 0 && k <= num_dims, "draw_round_dims: " << k << " of " << num_dims << " dims");
  std::vector<std::pair<uint64_t, int32_t>> keyed(static_cast<size_t>(num_dims));
  for (int32_t d = 0; d < num_dims; ++d) {
    keyed[d] = {counter_hash(seed, kDrawTag, static_cast<uint64_t>(round), static_cast<uint64_t>(d)), d};
  }
  std::nth_element(keyed.begin(), keyed.begin() + k, keyed.end());
  std::vector<int32_t> dims;
  dims.reserve(static_cast<size_t>(k));
  for (int32_t i = 0; i < k; ++i) dims.push_back(keyed[i].second);
  std::sort(dims.begin(), dims.end());
  return dims;
}

SerialStumpLearner::SerialStumpLearner(const FeatureMatrix& features, const TrainingSet& set,
                                       const BoostOptions& options)
    : features_(features), set_(set), options_(options) {
  options_.check(features.num_dims);
  set_.check();
  LMB_CHECK(features.num_samples == set.num_samples(),
            "features: " << features.num_samples << " rows for " << set.num_samples() << " training samples");
  LMB_CHECK(static_cast<int64_t>(features.data.size()) ==
                static_cast<int64_t>(features.num_stored_columns()) * features.num_samples,
            "features: data holds " << features.data.size() << " bytes, expected "
                                    << features.num_stored_columns() << " columns x " << features.num_samples);
  LMB_CHECK(features.num_samples < std::numeric_limits<int32_t>::max(),
            "features: " << features.num_samples << " samples; at most 2^31 - 2 are supported");
  C1_ = set.num_classes_with_background();
  global_to_stored_.assign(static_cast<size_t>(features.num_dims), -1);
  for (int32_t i = 0; i < features.num_stored_columns(); ++i) {
    const int32_t d = features.dims.empty() ? i : features.dims[i];
    LMB_CHECK(d >= 0 && d < features.num_dims, "features: stored column " << i << " has dim " << d);
    global_to_stored_[d] = i;
  }
  build_layouts();
  model_.num_dims = features.num_dims;
  model_.num_classes = set.num_classes;
  model_.class_landmark = set.class_landmark;
  model_.bias.assign(static_cast<size_t>(C1_), 0.0);
  class_offset_.assign(static_cast<size_t>(C1_), 0.0);
}

int32_t SerialStumpLearner::stored_index(int32_t dim) const {
  return dim >= 0 && dim < static_cast<int32_t>(global_to_stored_.size()) ? global_to_stored_[dim] : -1;
}

void SerialStumpLearner::fill_buckets(DimLayout* layout) {
  size_t t = 0;
  for (int v = 0; v < 256; ++v) {
    while (t < layout->thresholds.size() && layout->thresholds[t] < v) ++t;
    layout->bucket[v] = static_cast<uint8_t>(t);
  }
}

SerialStumpLearner::DimLayout SerialStumpLearner::make_layout(const uint8_t* col) const {
  const int32_t max_t = options_.screening.max_thresholds;
  int64_t counts[256] = {0};
  for (int64_t s = 0; s < features_.num_samples; ++s) ++counts[col[s]];
  std::vector<uint8_t> distinct;
  for (int v = 0; v < 256; ++v) {
    if (counts[v]) distinct.push_back(static_cast<uint8_t>(v));
  }
  DimLayout layout;
  if (distinct.size() >= 2) {
    std::vector<uint8_t> cand(distinct.begin(), distinct.end() - 1);  // all but the largest
    if (max_t == 0 || static_cast<int32_t>(cand.size()) <= max_t) {
      layout.thresholds = cand;
    } else {
      // Smallest bin, then count-weighted quantiles of the others.
      layout.thresholds.push_back(cand[0]);
      int64_t total = 0;
      for (size_t j = 1; j < cand.size(); ++j) total += counts[cand[j]];
      int64_t cum = 0;
      size_t j = 1;
      for (int32_t q = 1; q < max_t; ++q) {
        const int64_t target = (total * q) / max_t;
        while (j < cand.size() && cum + counts[cand[j]] <= target) cum += counts[cand[j++]];
        const uint8_t v = cand[std::min(j, cand.size() - 1)];
        if (v > layout.thresholds.back()) layout.thresholds.push_back(v);
      }
    }
  }
  fill_buckets(&layout);
  int64_t above = 0;
  for (int v = 0; v < 256; ++v) above += layout.bucket[v] > 0 ? counts[v] : 0;
  layout.above_fraction = features_.num_samples > 0
                              ? static_cast<float>(static_cast<double>(above) / static_cast<double>(features_.num_samples))
                              : 0.f;
  return layout;
}

void SerialStumpLearner::build_layouts() {
  const int32_t n = features_.num_stored_columns();
  layouts_.resize(static_cast<size_t>(n));
  int32_t num_usable = 0;
  for (int32_t i = 0; i < n; ++i) {
    layouts_[i] = make_layout(features_.column(i));
    num_usable += !layouts_[i].thresholds.empty();
  }
  LMB_CHECK(n == 0 || num_usable > 0, "features: all " << n
                                          << " stored columns are constant; no stump can split them");
}

void SerialStumpLearner::initialize() {
  if (initialized_) return;
  bootstrap_negatives();
  // Tracked samples: validation rows (landmark classes), then the mining pool (train samples).
  std::vector<int64_t> validation, train;
  for (int64_t s = 0; s < set_.num_samples(); ++s) {
    if (set_.sample_is_validation[s]) {
      if (set_.sample_class[s] < set_.num_classes) validation.push_back(s);
    } else {
      train.push_back(s);
    }
  }
  tracked_samples_ = options_.validation.interval > 0
                         ? hash_subset(validation, options_.validation.max_samples, options_.seed, kValidationTag)
                         : std::vector<int64_t>{};
  num_validation_rows_ = static_cast<int64_t>(tracked_samples_.size());
  if (options_.mining.interval > 0) {
    const auto pool = hash_subset(train, options_.mining.pool_size, options_.seed, kPoolTag);
    tracked_samples_.insert(tracked_samples_.end(), pool.begin(), pool.end());
  }
  split_rows();
  tracked_scores_.assign(static_cast<size_t>(local_rows()) * static_cast<size_t>(C1_), 0.f);
  initialized_ = true;
}

void SerialStumpLearner::split_rows() {
  std::tie(row_part_, row_parts_) = work_part();
  LMB_CHECK(row_parts_ >= 1 && row_part_ >= 0 && row_part_ < row_parts_,
            "boost: work part " << row_part_ << " of " << row_parts_);
}

int64_t SerialStumpLearner::local_rows() const {
  const int64_t n = static_cast<int64_t>(tracked_samples_.size());
  return n > row_part_ ? (n - row_part_ + row_parts_ - 1) / row_parts_ : 0;
}

int64_t SerialStumpLearner::local_validation_rows() const {
  const int64_t n = num_validation_rows_;
  return n > row_part_ ? (n - row_part_ + row_parts_ - 1) / row_parts_ : 0;
}

void SerialStumpLearner::flush_pool_rows() {
  const int64_t v = local_validation_rows(), rows = local_rows();
  if (!pending_pool_.empty()) {
    for (int64_t i = v; i < rows; ++i) {
      float* row = tracked_scores_.data() + static_cast<size_t>(i) * C1_;
      for (const PendingStump& p : pending_pool_) {
        const float* d = p.above[i - v] ? p.d_above.data() : p.d_below.data();
        const size_t n = p.classes.size();
        for (size_t j = 0; j < n; ++j) row[p.classes[j]] += d[j];
      }
    }
  }
  pending_pool_.clear();
}

void SerialStumpLearner::bootstrap_negatives() {
  const int32_t C = set_.num_classes;
  const int64_t S = set_.num_samples();
  const double radius = options_.negatives.exclusion_radius;
  auto initial_weight = [&](int64_t s) { return set_.sample_weight.empty() ? 1.0 : static_cast<double>(set_.sample_weight[s]); };
  auto excluded = [&](int32_t c, int64_t s) {
    if (c >= C || radius <= 0.0) return false;
    const Eigen::Vector3f& p = set_.sample_position[s];
    if (!p.allFinite()) return false;
    return (p.cast<double>() - set_.class_position[c]).norm() < radius;
  };

  std::vector<int64_t> samples;
  std::vector<int32_t> codes;
  std::vector<double> weights;
  std::vector<std::vector<int64_t>> positives(static_cast<size_t>(C1_));
  int32_t max_word = -1;
  for (int64_t s = 0; s < S; ++s) {
    if (set_.sample_is_validation[s]) continue;
    positives[set_.sample_class[s]].push_back(s);
    max_word = std::max(max_word, set_.sample_word[s]);
  }
  std::vector<std::vector<int64_t>> word_samples(static_cast<size_t>(max_word + 1));
  std::vector<int64_t> all_train, landmark_train;
  for (int64_t s = 0; s < S; ++s) {
    if (set_.sample_is_validation[s]) continue;
    if (set_.sample_word[s] >= 0) word_samples[set_.sample_word[s]].push_back(s);
    all_train.push_back(s);
    if (set_.sample_class[s] < C) landmark_train.push_back(s);
  }

  std::vector<const std::vector<int64_t>*> lists;
  std::vector<int64_t> prefix;
  std::vector<int64_t> chosen;
  std::vector<std::pair<uint64_t, int64_t>> keyed;
  negative_unit_.assign(static_cast<size_t>(C1_), 1.0);
  for (int32_t c = 0; c < C1_; ++c) {
    double positive_total = 0.0;
    for (int64_t s : positives[c]) {
      samples.push_back(s);
      codes.push_back(c * 2);
      weights.push_back(initial_weight(s));
      positive_total += initial_weight(s);
    }
    lists.clear();
    int32_t n_neg = options_.negatives.per_class;
    if (c == C) {
      lists.push_back(&landmark_train);
      if (options_.negatives.background > 0) {
        n_neg = options_.negatives.background;
      } else {
        n_neg = static_cast<int32_t>(std::min<size_t>(landmark_train.size(), std::numeric_limits<int32_t>::max()));
      }
    } else {
      std::vector<int32_t> words;
      for (int64_t s : positives[c]) {
        if (set_.sample_word[s] >= 0) words.push_back(set_.sample_word[s]);
      }
      std::sort(words.begin(), words.end());
      words.erase(std::unique(words.begin(), words.end()), words.end());
      for (int32_t w : words) lists.push_back(&word_samples[w]);
      if (words.empty()) lists.push_back(&all_train);
    }
    prefix.assign(1, 0);
    for (const auto* l : lists) prefix.push_back(prefix.back() + static_cast<int64_t>(l->size()));
    const int64_t M = prefix.back();
    auto accept = [&](int64_t s) { return set_.sample_class[s] != c && !excluded(c, s); };
    chosen.clear();
    if (M <= 4 * static_cast<int64_t>(n_neg) + 64) {
      keyed.clear();
      for (const auto* l : lists) {
        for (int64_t s : *l) {
          if (accept(s)) keyed.emplace_back(counter_hash(options_.seed, kNegativeTag, static_cast<uint64_t>(c), static_cast<uint64_t>(s)), s);
        }
      }
      const size_t take = std::min(keyed.size(), static_cast<size_t>(n_neg));
      std::partial_sort(keyed.begin(), keyed.begin() + static_cast<int64_t>(take), keyed.end());
      for (size_t i = 0; i < take; ++i) chosen.push_back(keyed[i].second);
    } else {
      const int64_t attempts = 16 * static_cast<int64_t>(n_neg) + 64;
      for (int64_t a = 0; a < attempts && static_cast<int32_t>(chosen.size()) < n_neg; ++a) {
        const uint64_t r = counter_hash(options_.seed, kNegativeTag, static_cast<uint64_t>(c), static_cast<uint64_t>(a) | (1ull << 63));
        const int64_t idx = static_cast<int64_t>(scale_to(r, static_cast<uint64_t>(M)));
        const size_t li = static_cast<size_t>(std::upper_bound(prefix.begin(), prefix.end(), idx) - prefix.begin() - 1);
        const int64_t s = (*lists[li])[idx - prefix[li]];
        if (!accept(s) || std::find(chosen.begin(), chosen.end(), s) != chosen.end()) continue;
        chosen.push_back(s);
      }
    }
    std::sort(chosen.begin(), chosen.end());
    // Balanced classes: the negatives share negative_weight_ratio x the positives' total weight.
    double negative_total = 0.0;
    for (int64_t s : chosen) negative_total += initial_weight(s);
    if (options_.negatives.weight_ratio > 0.0 && negative_total > 0.0 && positive_total > 0.0) {
      negative_unit_[c] = options_.negatives.weight_ratio * positive_total / negative_total;
    }
    for (int64_t s : chosen) {
      samples.push_back(s);
      codes.push_back(c * 2 + 1);
      weights.push_back(negative_unit_[c] * initial_weight(s));
    }
  }
  weight_exponent_ = 0;
  rebuild_entry_index(samples, codes, weights);
}

void SerialStumpLearner::rebuild_entry_index(std::vector<int64_t>& samples, std::vector<int32_t>& codes,
                                             std::vector<double>& weights) {
  const int64_t S = set_.num_samples();
  const size_t E = samples.size();
  std::vector<size_t> order(E);
  std::iota(order.begin(), order.end(), 0);
  const auto before = [&](size_t a, size_t b) {
    return samples[a] != samples[b] ? samples[a] < samples[b] : codes[a] < codes[b];
  };
  // Mining appends a few new entries to sorted ones: sort the unsorted tail and merge.
  size_t sorted = E == 0 ? 0 : 1;
  while (sorted < E && !before(sorted, sorted - 1)) ++sorted;
  std::sort(order.begin() + static_cast<int64_t>(sorted), order.end(), before);
  std::inplace_merge(order.begin(), order.begin() + static_cast<int64_t>(sorted), order.end(), before);
  sample_offset_.assign(static_cast<size_t>(S) + 1, 0);
  entry_code_.resize(E);
  entry_weight_.resize(E);
  class_negatives_.assign(static_cast<size_t>(C1_), {});
  for (size_t i = 0; i < E; ++i) {
    const size_t j = order[i];
    entry_code_[i] = codes[j];
    entry_weight_[i] = weights[j];
    ++sample_offset_[samples[j] + 1];
    if (codes[j] & 1) class_negatives_[codes[j] >> 1].push_back(samples[j]);  // ascending samples
  }
  for (int64_t s = 0; s < S; ++s) sample_offset_[s + 1] += sample_offset_[s];
  hot_.assign(E, HotEntry{0, 0, 0});
  for (size_t i = 0; i < E; ++i) hot_[i].code = entry_code_[i];
  // Class-major copy: counting sort on the code (2 c + neg) keeps each group's samples ascending.
  std::vector<int64_t> code_begin(static_cast<size_t>(C1_) * 2 + 1, 0);
  for (size_t i = 0; i < E; ++i) ++code_begin[static_cast<size_t>(entry_code_[i]) + 1];
  for (size_t i = 1; i < code_begin.size(); ++i) code_begin[i] += code_begin[i - 1];
  class_begin_.resize(static_cast<size_t>(C1_) + 1);
  class_neg_begin_.resize(static_cast<size_t>(C1_));
  for (int32_t c = 0; c < C1_; ++c) {
    class_begin_[c] = code_begin[2 * static_cast<size_t>(c)];
    class_neg_begin_[c] = code_begin[2 * static_cast<size_t>(c) + 1];
  }
  class_begin_[C1_] = code_begin.back();
  class_index_.resize(E);
  class_sample_.assign(E + 32, 0);  // padding: screen_block prefetches ahead
  class_wq_.assign(E, 0);
  for (int64_t s = 0; s < S; ++s) {
    for (int64_t e = sample_offset_[s]; e < sample_offset_[s + 1]; ++e) {
      const int64_t j = code_begin[static_cast<size_t>(entry_code_[e])]++;
      class_index_[e] = j;
      class_sample_[j] = static_cast<int32_t>(s);
    }
  }
}

void SerialStumpLearner::quantize_weights() {
  double local_max = 0.0;
  for (double w : entry_weight_) {
    LMB_CHECK(std::isfinite(w), "boost: a weight became non-finite at round " << rounds_done());
    local_max = std::max(local_max, w);
  }
  double global_max = reduce_max(local_max);
  LMB_CHECK(global_max > 0.0, "boost: every entry weight is zero at round " << rounds_done());
  // Keep stored weights near 1: exact power-of-two rescaling.
  const int e = std::ilogb(global_max);
  if (e > 64 || e < -64) {
    for (double& w : entry_weight_) w = std::ldexp(w, -e);
    weight_exponent_ += e;
    global_max = std::ldexp(global_max, -e);
  }
  const int64_t num_entries = reduce_sum(static_cast<int64_t>(entry_weight_.size()));
  const int bits = std::bit_width(static_cast<uint64_t>(num_entries) + 1);
  // Every quantised weight is < 2^(52 - bits), so any sum of entries is an integer below 2^52:
  // exact in a double too, which lets the screening convert and add sums in SIMD doubles without
  // rounding (order-free, like the int64 sums). The smallest weight kept is ~2^-32 of the largest
  // at 600,000 entries; a lighter one rounds to 0 and moves no gain by more than that fraction.
  const int shift = 52 - bits - (std::ilogb(global_max) + 1);
  LMB_CHECK(shift > -1000 && shift < 1000, "boost: weight scale 2^" << shift << " at round " << rounds_done());
  quant_shift_ = shift;
  class_w_.assign(static_cast<size_t>(C1_), 0);
  class_y_.assign(static_cast<size_t>(C1_), 0);
  const size_t E = entry_weight_.size();
  // w * 2^shift is ldexp(w, shift) (a product with a normal power of two rounds like ldexp), and
  // for 0 <= x < 2^52 truncation plus a half-up step is llround(x): no libm call per entry.
  const double scale = std::ldexp(1.0, shift);
  for (size_t i = 0; i < E; ++i) {
    const double x = entry_weight_[i] * scale;
    int64_t q = static_cast<int64_t>(x);
    q += x - static_cast<double>(q) >= 0.5;
    hot_[i].wq = q;
    class_wq_[class_index_[i]] = q;
    const int32_t c = entry_code_[i] >> 1;
    class_w_[c] += q;
    class_y_[c] += (entry_code_[i] & 1) ? -q : q;
  }
  reduce_class_totals(&class_w_, &class_y_);
  class_q_.resize(static_cast<size_t>(C1_));
  for (int32_t c = 0; c < C1_; ++c) {
    const double y = static_cast<double>(class_y_[c]);
    class_q_[c] = class_w_[c] > 0 ? y * y / static_cast<double>(class_w_[c]) : 0.0;
  }
}

void SerialStumpLearner::scatter_dim(const uint8_t* col, const DimLayout& layout) {
  const int32_t T = static_cast<int32_t>(layout.thresholds.size());
  const size_t plane = static_cast<size_t>(C1_) * 2;  // one bucket: (P, N) per class
  if (hist_.size() < plane * T) hist_.resize(plane * T, 0);
  const uint8_t* bucket = layout.bucket;
  const int64_t S = features_.num_samples;
  // Pass 1: the samples above the smallest threshold t0, 16 bins at a time: v > t0 <=> max(v, t0 + 1) == v.
  nonzero_.clear();
  const uint8_t t0 = layout.thresholds[0];
  const __m128i t0p1 = _mm_set1_epi8(static_cast<char>(t0 + 1));
  int64_t s = 0;
  for (; s + 16 <= S; s += 16) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(col + s));
    uint32_t mask = static_cast<uint32_t>(_mm_movemask_epi8(_mm_cmpeq_epi8(_mm_max_epu8(v, t0p1), v)));
    while (mask) {
      const int64_t k = s + __builtin_ctz(mask);
      mask &= mask - 1;
      nonzero_.emplace_back(static_cast<int32_t>(k), bucket[col[k]]);
    }
  }
  for (; s < S; ++s) {
    const int b = bucket[col[s]];
    if (b) nonzero_.emplace_back(static_cast<int32_t>(s), b);
  }
  // Pass 2: scatter their entries' weights into per-(class, bucket) sums, prefetching ahead.
  const int64_t* off = sample_offset_.data();
  const HotEntry* hot = hot_.data();
  int64_t* hist = hist_.data();
  const size_t n = nonzero_.size();
  constexpr size_t kAhead = 16;
  constexpr size_t kRowAhead = 8;
  for (size_t i = 0; i < n; ++i) {
    if (i + kAhead < n) __builtin_prefetch(hot + off[nonzero_[i + kAhead].first]);
    if (i + kRowAhead < n) {
      // The entries of sample i + 8 were prefetched 8 iterations ago: prefetch their rows.
      const auto [sa, ba] = nonzero_[i + kRowAhead];
      const size_t base = static_cast<size_t>(ba - 1) * plane;
      for (int64_t e = off[sa]; e < off[sa + 1]; ++e) {
        __builtin_prefetch(hist + base + static_cast<size_t>(hot[e].code >> 1) * 2, 1);
      }
    }
    const auto [sample, b] = nonzero_[i];
    const int64_t end = off[sample + 1];
    int64_t* h = hist + static_cast<size_t>(b - 1) * plane;
    for (int64_t e = off[sample]; e < end; ++e) h[hot[e].code] += hot[e].wq;  // code = 2 c + neg
  }
}

void SerialStumpLearner::cumulate_hist(int32_t T) {
  // Bucket t becomes the sums above threshold t (buckets t+1..T, stored at t..T-1).
  const size_t plane = static_cast<size_t>(C1_) * 2;
  int64_t* hist = hist_.data();
  for (int32_t t = T - 2; t >= 0; --t) {
    int64_t* dst = hist + static_cast<size_t>(t) * plane;
    const int64_t* src = dst + plane;
    for (size_t i = 0; i < plane; ++i) dst[i] += src[i];
  }
}

int32_t SerialStumpLearner::collect_dim_sums(int32_t T) {
  cumulate_hist(T);
  const size_t plane = static_cast<size_t>(C1_) * 2;
  int64_t* hist = hist_.data();
  // Classes with any weight above the smallest threshold, ascending.
  touched_.clear();
  for (int32_t c = 0; c < C1_; ++c) {
    if (hist[2 * c] | hist[2 * c + 1]) touched_.push_back(c);
  }
  const int32_t m = static_cast<int32_t>(touched_.size());
  cum_p_.resize(static_cast<size_t>(T) * m);
  cum_n_.resize(static_cast<size_t>(T) * m);
  for (int32_t t = 0; t < T; ++t) {
    const int64_t* h = hist + static_cast<size_t>(t) * plane;
    for (int32_t j = 0; j < m; ++j) {
      cum_p_[static_cast<size_t>(t) * m + j] = h[2 * touched_[j]];
      cum_n_[static_cast<size_t>(t) * m + j] = h[2 * touched_[j] + 1];
    }
  }
  std::memset(hist, 0, plane * static_cast<size_t>(T) * sizeof(int64_t));
  return m;
}

int32_t SerialStumpLearner::prepare_threshold(int32_t m, int32_t t, int32_t /*num_thresholds*/) {
  // Only classes with weight above the threshold can gain from sharing (for the others
  // g_c(alpha, beta) = -wm (beta - k_c)^2 <= 0), so the search sees those alone.
  for (auto* v : {&wp_, &yp_, &wm_, &ym_}) v->resize(static_cast<size_t>(m));
  for (auto* v : {&wpd_, &ypd_, &wmd_, &ymd_, &q_}) v->resize(static_cast<size_t>(m));
  active_.resize(static_cast<size_t>(m));
  const int64_t* p = cum_p_.data() + static_cast<size_t>(t) * m;
  const int64_t* n = cum_n_.data() + static_cast<size_t>(t) * m;
  int32_t k = 0;
  for (int32_t j = 0; j < m; ++j) {
    const int64_t w = p[j] + n[j];
    const int32_t c = touched_[j];
    const int64_t y = p[j] - n[j];
    active_[k] = c;
    wp_[k] = w;
    yp_[k] = y;
    wm_[k] = class_w_[c] - w;
    ym_[k] = class_y_[c] - y;
    wpd_[k] = static_cast<double>(w);
    ypd_[k] = static_cast<double>(y);
    wmd_[k] = static_cast<double>(wm_[k]);
    ymd_[k] = static_cast<double>(ym_[k]);
    q_[k] = class_q_[c];
    k += w > 0;
  }
  return k;
}

namespace {
struct GroupSums {
  double wp = 0, yp = 0, wm = 0, ym = 0, q = 0;
  void add(double a, double b, double c, double d, double e) {
    wp += a;
    yp += b;
    wm += c;
    ym += d;
    q += e;
  }
  double gain() const { return (wp > 0 ? yp * yp / wp : 0.0) + (wm > 0 ? ym * ym / wm : 0.0) - q; }
  void point(double* alpha, double* beta) const {
    const double a = wp > 0 ? yp / wp : 0.0, b = wm > 0 ? ym / wm : 0.0;
    *alpha = wp > 0 ? a : b;
    *beta = wm > 0 ? b : a;
  }
};
}  // namespace

void SerialStumpLearner::screen_scattered(int32_t T, std::vector<double>* gains) {
  // screen_sharing_gain for every threshold of the scattered dim, straight from the cumulated
  // per-(bucket, class) sums: the rising / falling groups, then (screening_step) one alternation
  // step from each group's point. Zeroes the histogram.
  cumulate_hist(T);
  const size_t plane = static_cast<size_t>(C1_) * 2;
  int64_t* hist = hist_.data();
  const int64_t* cw = class_w_.data();
  const int64_t* cy = class_y_.data();
  const double* cq = class_q_.data();
  gains->resize(static_cast<size_t>(T));
  for (int32_t t = 0; t < T; ++t) {
    const int64_t* h = hist + static_cast<size_t>(t) * plane;
    double rwp = 0, ryp = 0, rwm = 0, rym = 0, rq = 0;
    double fwp = 0, fyp = 0, fwm = 0, fym = 0, fq = 0;
    // (Measured: branch-free masks with 20 accumulators were slower than these branches.)
    for (int32_t c = 0; c < C1_; ++c) {
      const int64_t p = h[2 * c], n = h[2 * c + 1];
      if ((p | n) == 0) continue;
      const double wp = static_cast<double>(p + n), yp = static_cast<double>(p - n);
      const double wm = static_cast<double>(cw[c] - (p + n)), ym = static_cast<double>(cy[c] - (p - n));
      const double lhs = yp * wm, rhs = ym * wp;
      if (lhs > rhs) {
        rwp += wp, ryp += yp, rwm += wm, rym += ym, rq += cq[c];
      } else if (lhs < rhs) {
        fwp += wp, fyp += yp, fwm += wm, fym += ym, fq += cq[c];
      }
    }
    GroupSums rise{rwp, ryp, rwm, rym, rq}, fall{fwp, fyp, fwm, fym, fq};
    double best = std::max(rise.gain(), fall.gain());
    if (options_.screening.step) {
      double ar, br, af, bf;
      rise.point(&ar, &br);
      fall.point(&af, &bf);
      const double ar2 = 2 * ar, arr = ar * ar, br2 = 2 * br, brr = br * br;
      const double af2 = 2 * af, aff = af * af, bf2 = 2 * bf, bff = bf * bf;
      double swp = 0, syp = 0, swm = 0, sym = 0, sq = 0;
      double twp = 0, typ = 0, twm = 0, tym = 0, tq = 0;
      for (int32_t c = 0; c < C1_; ++c) {
        const int64_t p = h[2 * c], n = h[2 * c + 1];
        const double wp = static_cast<double>(p + n), yp = static_cast<double>(p - n);
        const double wm = static_cast<double>(cw[c] - (p + n)), ym = static_cast<double>(cy[c] - (p - n));
        const double q = cq[c];
        if ((p | n) == 0) continue;  // never joins: g_c = -wm (beta - k_c)^2 <= 0
        if (ar2 * yp - arr * wp + br2 * ym - brr * wm - q > 0.0) swp += wp, syp += yp, swm += wm, sym += ym, sq += q;
        if (af2 * yp - aff * wp + bf2 * ym - bff * wm - q > 0.0) twp += wp, typ += yp, twm += wm, tym += ym, tq += q;
      }
      best = std::max({best, GroupSums{swp, syp, swm, sym, sq}.gain(), GroupSums{twp, typ, twm, tym, tq}.gain()});
    }
    (*gains)[t] = best;
  }
  std::memset(hist, 0, plane * static_cast<size_t>(T) * sizeof(int64_t));
}

namespace {
// Per threshold t < 16 of one dim, the rising and falling groups' sums (wp, yp, wm, ym, q).
struct ScreenGroups {
  double rise[5][16];
  double fall[5][16];
};

// Adds one class to the groups of thresholds 0 .. 4 * chunks - 1 of a dim, given the class's
// per-bucket sums of positive and negative weight (buckets 0..15; bucket b holds the samples with b
// thresholds below their value): what screen_scattered's loop body does for one class, without
// branches, four thresholds at a time. Every sum is an integer below 2^52 (quantize_weights), so
// int64 -> double conversion (by the 2^52 exponent trick), the sums above each threshold and the
// group sums of wp, yp, wm, ym are exact, as in screen_scattered; q sums in the same class order;
// a class that joins no group adds +0.0, which changes no sum.
using V4d = double __attribute__((vector_size(32), aligned(32)));
using V4l = int64_t __attribute__((vector_size(32), aligned(32)));
LMB_CLONES_AVX2 void add_screen_groups(const int64_t* bucket_p, const int64_t* bucket_n, int32_t chunks,
                                       int64_t class_w, int64_t class_y, double class_q, ScreenGroups* g) {
  const V4d zero = {0, 0, 0, 0};
  const V4l magic_bits = {0x4330000000000000, 0x4330000000000000, 0x4330000000000000, 0x4330000000000000};
  const double two52 = 4503599627370496.0;
  const V4d magic = {two52, two52, two52, two52};
  auto to_double = [&](V4l x) {  // exact for 0 <= x < 2^52
    V4d d;
    const V4l bits = x | magic_bits;
    std::memcpy(&d, &bits, sizeof(d));
    return d - magic;
  };
  // Inclusive prefix sums of a chunk: [a0, a0+a1, a0+a1+a2, a0+..+a3].
  auto prefix = [&](V4d x) {
    x += __builtin_shuffle(x, zero, V4l{4, 0, 1, 2});
    return x + __builtin_shuffle(x, zero, V4l{4, 4, 0, 1});
  };
  V4d incl_p[4], incl_n[4];
  V4d carry_p = zero, carry_n = zero;
  for (int32_t i = 0; i < 4; ++i) {
    incl_p[i] = prefix(to_double(*reinterpret_cast<const V4l*>(bucket_p + 4 * i))) + carry_p;
    incl_n[i] = prefix(to_double(*reinterpret_cast<const V4l*>(bucket_n + 4 * i))) + carry_n;
    carry_p = __builtin_shuffle(incl_p[i], V4l{3, 3, 3, 3});
    carry_n = __builtin_shuffle(incl_n[i], V4l{3, 3, 3, 3});
  }
  const double cw = static_cast<double>(class_w), cy = static_cast<double>(class_y);
  const V4d q = {class_q, class_q, class_q, class_q};
  for (int32_t i = 0; i < chunks; ++i) {
    const V4d p = carry_p - incl_p[i], n = carry_n - incl_n[i];  // above threshold t: buckets t+1..15
    const V4d wp = p + n, yp = p - n;
    const V4d wm = cw - wp, ym = cy - yp;
    const V4d lhs = yp * wm, rhs = ym * wp;
    const V4l up = lhs > rhs, down = lhs < rhs;
    const V4d fields[5] = {wp, yp, wm, ym, q};
    for (int f = 0; f < 5; ++f) {
      *reinterpret_cast<V4d*>(&g->rise[f][4 * i]) += up ? fields[f] : zero;
      *reinterpret_cast<V4d*>(&g->fall[f][4 * i]) += down ? fields[f] : zero;
    }
  }
}
// packed[i] = the bucket of sample i in column k (the number of its thresholds below the value)
// in bits 4k..4k+3, for k < count (<= 8); higher bits 0. Sixteen samples at a time with SSE2:
// bucket = sum over thresholds of [v > t], then a 4 x 16 byte transpose of the nibble pairs.
void pack_buckets(const uint8_t* const* cols, const uint8_t* const* thresholds, const int32_t* T, int32_t count,
                  int64_t S, uint32_t* packed) {
  int64_t i = 0;
  for (; i + 16 <= S; i += 16) {
    __m128i nib[4];
    for (int j = 0; j < 4; ++j) {
      __m128i pair[2] = {_mm_setzero_si128(), _mm_setzero_si128()};
      for (int h = 0; h < 2; ++h) {
        const int k = 2 * j + h;
        if (k >= count) continue;
        const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(cols[k] + i));
        __m128i b = _mm_setzero_si128();
        for (int32_t t = 0; t < T[k]; ++t) {
          const __m128i above = _mm_set1_epi8(static_cast<char>(thresholds[k][t] + 1));
          b = _mm_sub_epi8(b, _mm_cmpeq_epi8(_mm_max_epu8(v, above), v));  // v > t: -1
        }
        pair[h] = b;
      }
      nib[j] = _mm_or_si128(pair[0], _mm_slli_epi16(pair[1], 4));  // buckets <= 15: no carry
    }
    const __m128i lo01 = _mm_unpacklo_epi8(nib[0], nib[1]), hi01 = _mm_unpackhi_epi8(nib[0], nib[1]);
    const __m128i lo23 = _mm_unpacklo_epi8(nib[2], nib[3]), hi23 = _mm_unpackhi_epi8(nib[2], nib[3]);
    __m128i* out = reinterpret_cast<__m128i*>(packed + i);
    _mm_storeu_si128(out + 0, _mm_unpacklo_epi16(lo01, lo23));
    _mm_storeu_si128(out + 1, _mm_unpackhi_epi16(lo01, lo23));
    _mm_storeu_si128(out + 2, _mm_unpacklo_epi16(hi01, hi23));
    _mm_storeu_si128(out + 3, _mm_unpackhi_epi16(hi01, hi23));
  }
  for (; i < S; ++i) {
    uint32_t u = 0;
    for (int32_t k = 0; k < count; ++k) {
      uint32_t b = 0;
      for (int32_t t = 0; t < T[k]; ++t) b += cols[k][i] > thresholds[k][t];
      u |= b << (4 * k);
    }
    packed[i] = u;
  }
}

}  // namespace

void SerialStumpLearner::screen_block(const ColumnRef* refs, int32_t count, double* gains) {
  // Why class-major: a column pass touches the entries of every sample above the smallest
  // threshold, ~45% of them on the paper world (median dim), and scatters them across a 1 MB
  // histogram. Here every entry is streamed once per block of kBlockDims dims, reads one packed
  // word of its sample's buckets, and adds into per-class buckets that stay in L1; the screening
  // sums then run per class, for every (dim, threshold) of the block, in the same ascending class
  // order as screen_scattered, so each group sum sees the same additions in the same order.
  constexpr int K = kBlockDims;
  LMB_CHECK(count >= 1 && count <= K, "boost: screen_block of " << count << " dims");
  const int64_t S = features_.num_samples;
  packed_buckets_.resize(static_cast<size_t>(S) + 16);  // + the prefetch distance (zeros)
  uint32_t* packed = packed_buckets_.data();
  int32_t T[K] = {0};
  const uint8_t* cols[K];
  const uint8_t* thresholds[K];
  for (int32_t k = 0; k < count; ++k) {
    const DimLayout& layout = *refs[k].layout;
    T[k] = static_cast<int32_t>(layout.thresholds.size());
    LMB_CHECK(T[k] >= 1 && T[k] <= 15, "boost: screen_block: dim " << refs[k].dim << " has " << T[k] << " thresholds");
    cols[k] = refs[k].column;
    thresholds[k] = layout.thresholds.data();
  }
  pack_buckets(cols, thresholds, T, count, S, packed);
  std::fill(packed + S, packed + S + 16, 0u);
  alignas(64) ScreenGroups groups[K];
  std::memset(groups, 0, sizeof(groups));
  // Two copies of the per-class buckets, for even and odd entries: consecutive entries often hit
  // the same bucket, and one copy would chain each add to the previous one's store.
  alignas(64) int64_t acc[2][K][16];
  alignas(64) int64_t acc2[2][K][16];
  const int64_t* cw = class_w_.data();
  const int64_t* cy = class_y_.data();
  const double* cq = class_q_.data();
  const int32_t* sample = class_sample_.data();
  const int64_t* wq = class_wq_.data();
  for (int32_t c = 0; c < C1_; ++c) {
    const int64_t begin = class_begin_[c], mid = class_neg_begin_[c], end = class_begin_[c + 1];
    if (begin == end) continue;
    std::memset(acc, 0, sizeof(acc));
    std::memset(acc2, 0, sizeof(acc2));
    for (int side = 0; side < 2; ++side) {
      int64_t(*a)[16] = acc[side];
      int64_t(*b)[16] = acc2[side];
      int64_t e = side ? mid : begin;
      const int64_t e1 = side ? end : mid;
      for (; e + 2 <= e1; e += 2) {
        __builtin_prefetch(packed + sample[e + 16]);  // class_sample_ has 32 samples of padding
        __builtin_prefetch(packed + sample[e + 17]);
        const uint32_t u = packed[sample[e]], v = packed[sample[e + 1]];
        const int64_t w = wq[e], x = wq[e + 1];
        for (int k = 0; k < K; ++k) {
          a[k][(u >> (4 * k)) & 15u] += w;
          b[k][(v >> (4 * k)) & 15u] += x;
        }
      }
      if (e < e1) {
        const uint32_t u = packed[sample[e]];
        for (int k = 0; k < K; ++k) a[k][(u >> (4 * k)) & 15u] += wq[e];
      }
      for (int k = 0; k < K; ++k) {
        for (int j = 0; j < 16; ++j) a[k][j] += b[k][j];
      }
    }
    for (int32_t k = 0; k < count; ++k) {
      add_screen_groups(acc[0][k], acc[1][k], (T[k] + 3) / 4, cw[c], cy[c], cq[c], &groups[k]);
    }
  }
  for (int32_t k = 0; k < count; ++k) {
    const ScreenGroups& g = groups[k];
    for (int32_t t = 0; t < T[k]; ++t) {
      gains[k * 16 + t] = std::max(GroupSums{g.rise[0][t], g.rise[1][t], g.rise[2][t], g.rise[3][t], g.rise[4][t]}.gain(),
                                   GroupSums{g.fall[0][t], g.fall[1][t], g.fall[2][t], g.fall[3][t], g.fall[4][t]}.gain());
    }
  }
}

namespace {
SharingInput make_input(int32_t m, const std::vector<int64_t>& wp, const std::vector<int64_t>& yp,
                        const std::vector<int64_t>& wm, const std::vector<int64_t>& ym, const std::vector<double>& q) {
  SharingInput in;
  in.num_classes = m;
  in.wp = wp.data();
  in.yp = yp.data();
  in.wm = wm.data();
  in.ym = ym.data();
  in.q = q.data();
  return in;
}
}  // namespace

std::vector<int32_t> SerialStumpLearner::choose_dims(int32_t /*round*/, const std::vector<int32_t>& round_dims) {
  for (int32_t d : round_dims) {
    LMB_CHECK(column_ref(d).column, "boost: dim " << d << " of F_m is not stored in this feature matrix");
  }
  return round_dims;
}

std::vector<ScreenedCandidate> SerialStumpLearner::select_for_refinement(std::vector<ScreenedCandidate> local) {
  auto better = [](const ScreenedCandidate& x, const ScreenedCandidate& y) {
    if (x.gain != y.gain) return x.gain > y.gain;
    if (x.dim != y.dim) return x.dim < y.dim;
    return x.theta < y.theta;
  };
  const size_t keep = std::min(local.size(), static_cast<size_t>(options_.screening.refine_top));
  std::partial_sort(local.begin(), local.begin() + static_cast<int64_t>(keep), local.end(), better);
  local.resize(keep);
  return local;
}

SerialStumpLearner::ColumnRef SerialStumpLearner::column_ref(int32_t dim) const {
  const int32_t stored = stored_index(dim);
  if (stored >= 0) return {dim, features_.column(stored), &layouts_[stored]};
  for (const LentColumn& lent : lent_) {
    if (lent.dim == dim) return {dim, lent.column.data(), &lent.layout};
  }
  return {};
}

// Packed: S bins, the above fraction (float), the thresholds, their count (one byte, last).
std::vector<uint8_t> SerialStumpLearner::pack_column(int32_t dim) const {
  const ColumnRef ref = column_ref(dim);
  LMB_CHECK(ref.column, "boost: no column of dim " << dim << " here to lend");
  const size_t S = static_cast<size_t>(features_.num_samples);
  const std::vector<uint8_t>& t = ref.layout->thresholds;
  std::vector<uint8_t> packed(S + sizeof(float) + t.size() + 1);
  std::memcpy(packed.data(), ref.column, S);
  std::memcpy(packed.data() + S, &ref.layout->above_fraction, sizeof(float));
  std::copy(t.begin(), t.end(), packed.begin() + static_cast<int64_t>(S + sizeof(float)));
  packed.back() = static_cast<uint8_t>(t.size());
  return packed;
}

void SerialStumpLearner::lend_column(int32_t dim, std::vector<uint8_t> packed) {
  const size_t S = static_cast<size_t>(features_.num_samples);
  const size_t T = packed.empty() ? 0 : packed.back();
  LMB_CHECK(dim >= 0 && dim < features_.num_dims && packed.size() == S + sizeof(float) + T + 1,
            "boost: a lent column of dim " << dim << " has " << packed.size() << " bytes for " << S << " samples");
  if (column_ref(dim).column) return;
  LentColumn lent{dim, {}, {}};
  lent.layout.thresholds.assign(packed.begin() + static_cast<int64_t>(S + sizeof(float)), packed.end() - 1);
  std::memcpy(&lent.layout.above_fraction, packed.data() + S, sizeof(float));
  LMB_CHECK(std::is_sorted(lent.layout.thresholds.begin(), lent.layout.thresholds.end()) &&
                std::adjacent_find(lent.layout.thresholds.begin(), lent.layout.thresholds.end()) == lent.layout.thresholds.end(),
            "boost: a lent column of dim " << dim << " has unordered thresholds");
  fill_buckets(&lent.layout);
  packed.resize(S);
  lent.column = std::move(packed);
  lent_.push_back(std::move(lent));
}

int SerialStumpLearner::screening_kind(int32_t dim) const {
  const int32_t stored = stored_index(dim);
  LMB_CHECK(stored >= 0, "boost: screening_kind of dim " << dim << ", not stored here");
  return layout_kind(layouts_[stored]);
}

int SerialStumpLearner::layout_kind(const DimLayout& layout) const {
  const size_t T = layout.thresholds.size();
  if (T == 0) return 0;
  return T <= 15 && options_.screening.blocked && !options_.screening.step ? 1 : 2;
}

void SerialStumpLearner::stump_above(int32_t dim, int32_t theta, std::vector<uint8_t>* above) {
  const int32_t stored = stored_index(dim);
  LMB_CHECK(stored >= 0, "boost: stump dim " << dim << " is not stored in this feature matrix");
  const uint8_t* col = features_.column(stored);
  above->resize(static_cast<size_t>(features_.num_samples));
  for (int64_t s = 0; s < features_.num_samples; ++s) (*above)[s] = col[s] > theta;
}

std::vector<ScreenedCandidate> SerialStumpLearner::screen_dims(const std::vector<int32_t>& sorted_dims,
                                                               double* hist_seconds) {
  std::vector<ScreenedCandidate> screened;
  // Dims with at most 15 thresholds go through the blocked class-major pass (4-bit buckets)
  // unless screening_step needs the stored histogram; the others get a column pass each.
  std::vector<ColumnRef> block;
  auto flush_block = [&] {
    if (block.empty()) return;
    const auto th = Clock::now();
    double gains[kBlockDims * 16];
    screen_block(block.data(), static_cast<int32_t>(block.size()), gains);
    *hist_seconds += seconds_since(th);
    for (size_t k = 0; k < block.size(); ++k) {
      const DimLayout& layout = *block[k].layout;
      for (size_t t = 0; t < layout.thresholds.size(); ++t) {
        const double g = gains[k * 16 + t];
        if (g > 0.0) screened.push_back({g, block[k].dim, layout.thresholds[t], layout.above_fraction});
      }
    }
    block.clear();
  };
  for (int32_t d : sorted_dims) {
    const ColumnRef ref = column_ref(d);
    LMB_CHECK(ref.column, "boost: dim " << d << " is neither stored nor lent here");
    const DimLayout& layout = *ref.layout;
    const int32_t T = static_cast<int32_t>(layout.thresholds.size());
    const int kind = layout_kind(layout);
    if (kind == 0) continue;
    if (kind == 1) {
      block.push_back(ref);
      if (static_cast<int32_t>(block.size()) == kBlockDims) flush_block();
      continue;
    }
    const auto th = Clock::now();
    scatter_dim(ref.column, layout);
    *hist_seconds += seconds_since(th);
    screen_scattered(T, &screen_gains_);
    for (int32_t t = 0; t < T; ++t) {
      if (screen_gains_[t] > 0.0) screened.push_back({screen_gains_[t], d, layout.thresholds[t], layout.above_fraction});
    }
  }
  flush_block();
  return screened;
}

StumpRecord SerialStumpLearner::search_impl(const std::vector<int32_t>& dims, RoundStats* stats) {
  const auto t0 = Clock::now();
  double hist_seconds = 0.0;
  StumpRecord best;
  auto record_from = [&](const SharingResult& r, int32_t dim, int32_t theta) {
    StumpRecord rec;
    rec.gain = r.gain;
    rec.dim = dim;
    rec.theta = theta;
    rec.wp = r.wp;
    rec.yp = r.yp;
    rec.wm = r.wm;
    rec.ym = r.ym;
    rec.classes.reserve(r.members.size());
    for (int32_t i : r.members) rec.classes.push_back(active_[i]);
    return rec;
  };
  const SharingSearchOptions& full = options_.sharing;

  std::vector<int32_t> sorted_dims = dims;
  std::sort(sorted_dims.begin(), sorted_dims.end());
  if (options_.screening.refine_top == 0) {
    for (int32_t d : sorted_dims) {
      const ColumnRef ref = column_ref(d);
      LMB_CHECK(ref.column, "boost: dim " << d << " is neither stored nor lent here");
      const DimLayout& layout = *ref.layout;
      if (layout.thresholds.empty()) continue;
      const auto th = Clock::now();
      scatter_dim(ref.column, layout);
      const int32_t T = static_cast<int32_t>(layout.thresholds.size());
      const int32_t m = collect_dim_sums(T);
      hist_seconds += seconds_since(th);
      for (int32_t t = 0; t < T; ++t) {
        const int32_t k = prepare_threshold(m, t, T);
        const SharingResult r = find_sharing_set(make_input(k, wp_, yp_, wm_, ym_, q_), full, &sharing_scratch_);
        if (r.members.empty()) continue;
        StumpRecord rec = record_from(r, d, layout.thresholds[t]);
        if (stump_better(rec, best)) best = std::move(rec);
      }
    }
  } else {
    std::vector<ScreenedCandidate> screened = screen_dims(sorted_dims, &hist_seconds);
    std::vector<ScreenedCandidate> chosen = select_for_refinement(std::move(screened));
    std::sort(chosen.begin(), chosen.end(), [](const auto& x, const auto& y) {
      return x.dim != y.dim ? x.dim < y.dim : x.theta < y.theta;
    });
    int32_t current_dim = -1, m = 0;
    ColumnRef ref;
    for (const ScreenedCandidate& cand : chosen) {
      if (cand.dim != current_dim) {
        ref = column_ref(cand.dim);
        LMB_CHECK(ref.column, "boost: refinement candidate dim " << cand.dim << " is neither stored nor lent here");
        scatter_dim(ref.column, *ref.layout);
        m = collect_dim_sums(static_cast<int32_t>(ref.layout->thresholds.size()));
        current_dim = cand.dim;
      }
      const DimLayout& layout = *ref.layout;
      const auto it = std::find(layout.thresholds.begin(), layout.thresholds.end(), static_cast<uint8_t>(cand.theta));
      LMB_CHECK(it != layout.thresholds.end(), "boost: threshold " << cand.theta << " is not a candidate of dim " << cand.dim);
      const int32_t t = static_cast<int32_t>(it - layout.thresholds.begin());
      const int32_t k = prepare_threshold(m, t, static_cast<int32_t>(layout.thresholds.size()));
      const SharingResult r = find_sharing_set(make_input(k, wp_, yp_, wm_, ym_, q_), full, &sharing_scratch_);
      if (r.members.empty()) continue;
      StumpRecord rec = record_from(r, cand.dim, cand.theta);
      if (stump_better(rec, best)) best = std::move(rec);
    }
  }
  if (stats) {
    stats->seconds_histogram += hist_seconds;
    stats->seconds_search += seconds_since(t0) - hist_seconds;
  }
  return best;
}

std::vector<ScreenedCandidate> SerialStumpLearner::screen(std::vector<int32_t> dims) {
  initialize();
  quantize_weights();
  std::sort(dims.begin(), dims.end());
  double seconds = 0.0;
  std::vector<ScreenedCandidate> out = screen_dims(dims, &seconds);
  std::sort(out.begin(), out.end(), [](const auto& x, const auto& y) {
    return x.dim != y.dim ? x.dim < y.dim : x.theta < y.theta;
  });
  return out;
}

StumpRecord SerialStumpLearner::search(const std::vector<int32_t>& dims) {
  initialize();
  quantize_weights();
  return search_impl(dims, nullptr);
}

RoundStats SerialStumpLearner::run_round() {
  initialize();
  const auto t0 = Clock::now();
  RoundStats stats;
  stats.round = rounds_done();
  LMB_CHECK(stats.round < options_.num_rounds, "boost: all " << options_.num_rounds << " rounds are done");
  if (options_.mining.interval > 0 && stats.round > 0 && stats.round % options_.mining.interval == 0) {
    const auto tm = Clock::now();
    stats.mined = mine_hard_negatives();
    stats.seconds_eval += seconds_since(tm);
  }
  quantize_weights();
  stats.cost_before = exp_loss();
  lent_.clear();

  const std::vector<int32_t> round_dims =
      draw_round_dims(options_.seed, stats.round,
                      options_.candidate_dims > 0 ? options_.candidate_dims : features_.num_dims,
                      options_.dims_per_round);
  const StumpRecord best = reduce_best(search_impl(choose_dims(stats.round, round_dims), &stats));

  const auto tu = Clock::now();
  // Fit: k_c for every class, (alpha, beta) for the sharing set.
  std::vector<double> k(static_cast<size_t>(C1_));
  for (int32_t c = 0; c < C1_; ++c) {
    k[c] = class_w_[c] > 0 ? static_cast<double>(class_y_[c]) / static_cast<double>(class_w_[c]) : 0.0;
  }
  std::vector<uint8_t> in_s(static_cast<size_t>(C1_), 0);
  double alpha = 0.0, beta = 0.0;
  std::vector<uint8_t> above;
  SharedStump stump;
  const double nu = options_.learning_rate;
  for (double& kc : k) kc *= nu;
  if (best.valid()) {
    for (int32_t c : best.classes) in_s[c] = 1;
    fit_alpha_beta(best, &alpha, &beta);
    alpha *= nu;
    beta *= nu;
    stump_above(best.dim, best.theta, &above);
    stump.dim = best.dim;
    stump.theta = static_cast<uint8_t>(best.theta);
    stump.a = alpha - beta;
    stump.b = beta;
    stump.classes = best.classes;
  } else {
    above.assign(static_cast<size_t>(features_.num_samples), 0);
  }
  // Weight update w <- w exp(-z h) and the squared error of the fit. exp(-z h) takes few values:
  // exp(-/+ alpha) and exp(-/+ beta) in the sharing set, exp(-/+ k_c) outside it; tabulated once.
  double squared_error = 0.0, cost = 0.0;
  const int64_t S = set_.num_samples();
  std::vector<double> factor(static_cast<size_t>(C1_) * 2);  // [2 c + neg]: exp(-z k_c)
  for (int32_t c = 0; c < C1_; ++c) {
    factor[2 * c] = std::exp(-k[c]);
    factor[2 * c + 1] = std::exp(k[c]);
  }
  const double factor_above[2] = {std::exp(-alpha), std::exp(alpha)};
  const double factor_below[2] = {std::exp(-beta), std::exp(beta)};
  for (int64_t s = 0; s < S; ++s) {
    const double h_in = above[s] ? alpha : beta;
    const double* f_in = above[s] ? factor_above : factor_below;
    for (int64_t e = sample_offset_[s]; e < sample_offset_[s + 1]; ++e) {
      const int32_t code = entry_code_[e];
      const int32_t c = code >> 1;
      const double z = (code & 1) ? -1.0 : 1.0;
      const bool shared = in_s[c];
      const double h = shared ? h_in : k[c];
      const double w = entry_weight_[e];
      squared_error += w * (z - h) * (z - h);
      const double nw = w * (shared ? f_in[code & 1] : factor[code]);
      entry_weight_[e] = nw;
      cost += nw;
    }
  }
  const double scale = std::ldexp(1.0, weight_exponent_);
  stats.squared_error = squared_error * scale;
  stats.cost = cost * scale;
  LMB_CHECK(std::isfinite(stats.cost) && std::isfinite(stats.squared_error),
            "boost: the training cost became non-finite at round " << stats.round);
  // Tracked scores: score(s, c) = class_offset_[c] + tracked_scores_[row, c].
  if (best.valid()) {
    const size_t n = best.classes.size();
    std::vector<float> d_above(n), d_below(n);
    for (size_t j = 0; j < n; ++j) {
      d_above[j] = static_cast<float>(alpha - k[best.classes[j]]);
      d_below[j] = static_cast<float>(beta - k[best.classes[j]]);
    }
    const int64_t v = local_validation_rows(), rows = local_rows();
    if (n * 4 > static_cast<size_t>(C1_)) {
      // A large sharing set: add dense rows of changes (0 outside S, and x + 0.0f == x for the
      // scores, which are never -0), a vectorised stream instead of scattered adds.
      std::vector<float> dense[2] = {std::vector<float>(static_cast<size_t>(C1_), 0.f),
                                     std::vector<float>(static_cast<size_t>(C1_), 0.f)};
      for (size_t j = 0; j < n; ++j) {
        dense[0][best.classes[j]] = d_below[j];
        dense[1][best.classes[j]] = d_above[j];
      }
      for (int64_t i = 0; i < v; ++i) {
        float* row = tracked_scores_.data() + static_cast<size_t>(i) * C1_;
        const float* d = dense[above[tracked_samples_[row_part_ + i * row_parts_]]].data();
        for (int32_t c = 0; c < C1_; ++c) row[c] += d[c];
      }
    } else {
      for (int64_t i = 0; i < v; ++i) {
        float* row = tracked_scores_.data() + static_cast<size_t>(i) * C1_;
        const float* d = above[tracked_samples_[row_part_ + i * row_parts_]] ? d_above.data() : d_below.data();
        for (size_t j = 0; j < n; ++j) row[best.classes[j]] += d[j];
      }
    }
    if (rows > v) {
      PendingStump p;
      p.classes = best.classes;
      p.above.resize(static_cast<size_t>(rows - v));
      for (int64_t i = v; i < rows; ++i) p.above[i - v] = above[tracked_samples_[row_part_ + i * row_parts_]];
      p.d_above = std::move(d_above);
      p.d_below = std::move(d_below);
      pending_pool_.push_back(std::move(p));
    }
  }
  for (int32_t c = 0; c < C1_; ++c) {
    class_offset_[c] += k[c];
    if (!in_s[c]) model_.bias[c] += k[c];
  }
  model_.stumps.push_back(std::move(stump));
  stats.seconds_update = seconds_since(tu);

  // The gain is in this round's fixed-point units.
  stats.gain = best.valid() ? std::ldexp(best.gain, weight_exponent_ - quant_shift_) : 0.0;
  stats.dim = best.dim;
  stats.theta = best.theta;
  stats.sharing_size = static_cast<int32_t>(best.classes.size());
  stats.num_entries = static_cast<int64_t>(entry_weight_.size());
  if (options_.validation.interval > 0 &&
      ((stats.round + 1) % options_.validation.interval == 0 || stats.round + 1 == options_.num_rounds)) {
    const auto tv = Clock::now();
    evaluate_validation(&stats);
    stats.seconds_eval += seconds_since(tv);
  }
  stats.seconds = seconds_since(t0);
  return stats;
}

void SerialStumpLearner::train(const std::function<void(const RoundStats&)>& on_round) {
  while (rounds_done() < options_.num_rounds) {
    const RoundStats stats = run_round();
    if (on_round) on_round(stats);
  }
}

double SerialStumpLearner::exp_loss() const {
  double sum = 0.0;
  for (double w : entry_weight_) sum += w;
  return sum * std::ldexp(1.0, weight_exponent_);
}

std::vector<SerialStumpLearner::Entry> SerialStumpLearner::entries() const {
  std::vector<Entry> out;
  out.reserve(entry_weight_.size());
  const double scale = std::ldexp(1.0, weight_exponent_);
  for (int64_t s = 0; s + 1 < static_cast<int64_t>(sample_offset_.size()); ++s) {
    for (int64_t e = sample_offset_[s]; e < sample_offset_[s + 1]; ++e) {
      out.push_back({s, entry_code_[e] >> 1, static_cast<int8_t>((entry_code_[e] & 1) ? -1 : 1), entry_weight_[e] * scale});
    }
  }
  return out;
}

namespace {
// The first c in [0, n) with the largest offset[c] + row[c] (finite doubles), and that score: the
// maximum four lanes at a time, then the first class that reaches it (the same double sums, so
// the equality is exact).
LMB_CLONES_AVX2 int32_t first_max_score(const double* offset, const float* row, int32_t n, double* best) {
  using V4 = double __attribute__((vector_size(32)));
  using F4 = float __attribute__((vector_size(16)));
  double m = -std::numeric_limits<double>::infinity();
  int32_t c = 0;
  if (n >= 4) {
    V4 vm = {m, m, m, m};
    for (; c + 4 <= n; c += 4) {
      V4 o;
      F4 f;
      std::memcpy(&o, offset + c, sizeof(o));
      std::memcpy(&f, row + c, sizeof(f));
      const V4 s = o + __builtin_convertvector(f, V4);
      vm = s > vm ? s : vm;
    }
    m = std::max(std::max(vm[0], vm[1]), std::max(vm[2], vm[3]));
  }
  for (; c < n; ++c) m = std::max(m, offset[c] + static_cast<double>(row[c]));
  for (c = 0; c < n; ++c) {
    if (offset[c] + static_cast<double>(row[c]) == m) break;
  }
  *best = m;
  return c;
}
}  // namespace

void SerialStumpLearner::count_validation_hits(int64_t* all, int64_t* landmarks) const {
  // A row's best landmark class is the first maximum over the landmark classes; the background
  // class then wins the row only if it scores strictly higher (the first maximum over all
  // classes, as it comes last).
  const int32_t C = C1_ - 1;
  *all = *landmarks = 0;
  for (int64_t r = row_part_, i = 0; r < num_validation_rows_; r += row_parts_, ++i) {
    const float* row = tracked_scores_.data() + static_cast<size_t>(i) * C1_;
    double best_score = 0.0;
    const int32_t best = first_max_score(class_offset_.data(), row, C, &best_score);
    const int32_t truth = set_.sample_class[tracked_samples_[r]];
    *landmarks += best == truth;
    *all += best == truth && !(class_offset_[C] + row[C] > best_score);
  }
}

double SerialStumpLearner::validation_precision(bool exclude_background) {
  if (num_validation_rows_ == 0) return -1.0;
  int64_t all = 0, landmarks = 0;
  count_validation_hits(&all, &landmarks);
  const int64_t hits = sum_over_parts(exclude_background ? landmarks : all);
  return static_cast<double>(hits) / static_cast<double>(num_validation_rows_);
}

void SerialStumpLearner::evaluate_validation(RoundStats* stats) {
  if (num_validation_rows_ == 0) {
    stats->validation_p1 = stats->validation_p1_landmarks = last_validation_ = -1.0;
    return;
  }
  int64_t all = 0, landmarks = 0;
  count_validation_hits(&all, &landmarks);
  all = sum_over_parts(all);
  landmarks = sum_over_parts(landmarks);
  const double n = static_cast<double>(num_validation_rows_);
  stats->validation_p1 = static_cast<double>(all) / n;
  stats->validation_p1_landmarks = static_cast<double>(landmarks) / n;
  last_validation_ = stats->validation_p1;
}

int64_t SerialStumpLearner::mine_hard_negatives() {
  const int32_t C = set_.num_classes;
  const double radius = options_.negatives.exclusion_radius;
  const int32_t per_sample = options_.mining.per_sample;
  std::vector<int64_t> new_samples;
  std::vector<int32_t> new_codes;
  std::vector<double> new_weights;
  std::vector<std::pair<float, int32_t>> top;
  const double log_scale = static_cast<double>(weight_exponent_) * std::log(2.0);
  flush_pool_rows();
  // 1. This part's pool rows: the classes ranked at or above the true one, best first.
  struct Offer {
    int64_t row;
    int32_t cls;
    float score;
  };
  std::vector<Offer> offers;
  const int64_t V = num_validation_rows_, N = static_cast<int64_t>(tracked_samples_.size());
  const int64_t first = V <= row_part_ ? row_part_ : row_part_ + (V - row_part_ + row_parts_ - 1) / row_parts_ * row_parts_;
  for (int64_t r = first; r < N; r += row_parts_) {
    const int64_t s = tracked_samples_[r];
    const int32_t y = set_.sample_class[s];
    const float* row = tracked_scores_.data() + static_cast<size_t>((r - row_part_) / row_parts_) * C1_;
    const double sy = class_offset_[y] + row[y];
    top.clear();
    for (int32_t c = 0; c < C1_; ++c) {
      if (c == y) continue;
      const float sc = static_cast<float>(class_offset_[c] + row[c]);
      if (sc < sy) continue;
      if (static_cast<int32_t>(top.size()) == per_sample && !(sc > top.back().first)) continue;
      auto pos = std::find_if(top.begin(), top.end(), [&](const auto& t) { return sc > t.first; });
      top.insert(pos, {sc, c});
      if (static_cast<int32_t>(top.size()) > per_sample) top.pop_back();
    }
    for (const auto& [sc, c] : top) offers.push_back({r, c, sc});
  }
  // 2. Every part's offers, by row (a part's are by row, best first within a row), then the same
  //    sequential admission on every part: the caps make the order matter.
  {
    std::vector<uint8_t> bytes(offers.size() * sizeof(Offer));
    if (!offers.empty()) std::memcpy(bytes.data(), offers.data(), bytes.size());
    bytes = gather_parts(bytes);
    LMB_CHECK(bytes.size() % sizeof(Offer) == 0, "boost: mining offers of " << bytes.size() << " bytes are torn");
    offers.resize(bytes.size() / sizeof(Offer));
    if (!offers.empty()) std::memcpy(offers.data(), bytes.data(), bytes.size());
    std::stable_sort(offers.begin(), offers.end(), [](const Offer& a, const Offer& b) { return a.row < b.row; });
  }
  for (const Offer& offer : offers) {
    const int64_t s = tracked_samples_[offer.row];
    const int32_t c = offer.cls;
    const float sc = offer.score;
    auto& negs = class_negatives_[c];
    if (static_cast<int32_t>(negs.size()) >= options_.negatives.max_per_class) continue;
    auto it = std::lower_bound(negs.begin(), negs.end(), s);
    if (it != negs.end() && *it == s) continue;
    if (c < C && radius > 0.0) {
      const Eigen::Vector3f& p = set_.sample_position[s];
      if (p.allFinite() && (p.cast<double>() - set_.class_position[c]).norm() < radius) continue;
    }
    negs.insert(it, s);
    new_samples.push_back(s);
    new_codes.push_back(c * 2 + 1);
    // A negative's weight is its initial weight times exp(-z H) = exp(H(s, c)), stored relative
    // to 2^weight_exponent_: the weight it would have had in L-_c from the start.
    const double w0 = negative_unit_[c] * (set_.sample_weight.empty() ? 1.0 : static_cast<double>(set_.sample_weight[s]));
    new_weights.push_back(w0 * std::exp(static_cast<double>(sc) - log_scale));
  }
  if (new_samples.empty()) return 0;
  std::vector<int64_t> samples;
  std::vector<int32_t> codes;
  std::vector<double> weights;
  const size_t E = entry_weight_.size() + new_samples.size();
  samples.reserve(E);
  codes.reserve(E);
  weights.reserve(E);
  for (int64_t s = 0; s + 1 < static_cast<int64_t>(sample_offset_.size()); ++s) {
    for (int64_t e = sample_offset_[s]; e < sample_offset_[s + 1]; ++e) {
      samples.push_back(s);
      codes.push_back(entry_code_[e]);
      weights.push_back(entry_weight_[e]);
    }
  }
  samples.insert(samples.end(), new_samples.begin(), new_samples.end());
  codes.insert(codes.end(), new_codes.begin(), new_codes.end());
  weights.insert(weights.end(), new_weights.begin(), new_weights.end());
  rebuild_entry_index(samples, codes, weights);
  return static_cast<int64_t>(new_samples.size());
}

SerialStumpLearner::State SerialStumpLearner::save_state() {
  initialize();
  State st;
  st.model = model_;
  st.entry_code = entry_code_;
  st.entry_weight = entry_weight_;
  st.entry_sample.reserve(entry_code_.size());
  for (int64_t s = 0; s + 1 < static_cast<int64_t>(sample_offset_.size()); ++s) {
    for (int64_t e = sample_offset_[s]; e < sample_offset_[s + 1]; ++e) st.entry_sample.push_back(s);
  }
  st.weight_exponent = weight_exponent_;
  st.tracked_samples = tracked_samples_;
  st.num_validation_rows = num_validation_rows_;
  // Every part's rows, gathered to part 0 and put back in global row order: part p's local row i
  // is global row p + i * parts.
  flush_pool_rows();
  const size_t N = tracked_samples_.size();
  if (row_part_ == 0) st.tracked_scores.resize(N * static_cast<size_t>(C1_));
  const auto* mine = reinterpret_cast<const uint8_t*>(tracked_scores_.data());
  gather_parts_to_first(mine, static_cast<int64_t>(tracked_scores_.size() * sizeof(float)),
                        [&](int p, const uint8_t* bytes, int64_t size) {
    const size_t row_bytes = static_cast<size_t>(C1_) * sizeof(float);
    const size_t rows = N > static_cast<size_t>(p) ? (N - p + row_parts_ - 1) / row_parts_ : 0;
    LMB_CHECK(static_cast<size_t>(size) == rows * row_bytes,
              "boost: part " << p << " sent " << size << " bytes of tracked scores for " << rows << " rows x " << C1_ << " classes");
    for (size_t i = 0; i < rows; ++i) {
      std::memcpy(st.tracked_scores.data() + (p + i * row_parts_) * C1_, bytes + i * row_bytes, row_bytes);
    }
  });
  st.class_offset = class_offset_;
  st.negative_unit = negative_unit_;
  st.last_validation = last_validation_;
  return st;
}

void SerialStumpLearner::restore_state(const State& st) {
  const int64_t S = set_.num_samples();
  const size_t E = st.entry_sample.size();
  LMB_CHECK(st.entry_code.size() == E && st.entry_weight.size() == E,
            "learner state: " << E << " entry samples but " << st.entry_code.size() << " codes and "
                              << st.entry_weight.size() << " weights");
  for (size_t i = 0; i < E; ++i) {
    LMB_CHECK(st.entry_sample[i] >= 0 && st.entry_sample[i] < S,
              "learner state: entry " << i << " has sample " << st.entry_sample[i] << " of " << S);
    LMB_CHECK(st.entry_code[i] >= 0 && (st.entry_code[i] >> 1) < C1_,
              "learner state: entry " << i << " has class " << (st.entry_code[i] >> 1) << " of " << C1_);
    LMB_CHECK(std::isfinite(st.entry_weight[i]) && st.entry_weight[i] >= 0.0,
              "learner state: entry " << i << " has weight " << st.entry_weight[i]);
    LMB_CHECK(i == 0 || st.entry_sample[i - 1] < st.entry_sample[i] ||
                  (st.entry_sample[i - 1] == st.entry_sample[i] && st.entry_code[i - 1] < st.entry_code[i]),
              "learner state: entries are not in (sample, code) order at " << i);
  }
  LMB_CHECK(static_cast<int64_t>(st.model.bias.size()) == C1_ && static_cast<int64_t>(st.class_offset.size()) == C1_,
            "learner state: " << st.model.bias.size() << " biases and " << st.class_offset.size()
                              << " class offsets for " << C1_ << " classes");
  LMB_CHECK(st.model.num_dims == features_.num_dims && st.model.num_classes == set_.num_classes,
            "learner state: a model of " << st.model.num_classes << " classes x " << st.model.num_dims
                                         << " dims for " << set_.num_classes << " x " << features_.num_dims);
  LMB_CHECK(static_cast<int32_t>(st.model.stumps.size()) <= options_.num_rounds,
            "learner state: " << st.model.stumps.size() << " rounds done, more than boost.num_rounds "
                              << options_.num_rounds);
  st.model.check();
  LMB_CHECK(static_cast<int64_t>(st.negative_unit.size()) == C1_,
            "learner state: " << st.negative_unit.size() << " negative weights for " << C1_ << " classes");
  for (double u : st.negative_unit) {
    LMB_CHECK(std::isfinite(u) && u > 0.0, "learner state: negative weight " << u);
  }
  LMB_CHECK(st.num_validation_rows >= 0 && st.num_validation_rows <= static_cast<int64_t>(st.tracked_samples.size()),
            "learner state: " << st.num_validation_rows << " validation rows of " << st.tracked_samples.size());
  for (int64_t s : st.tracked_samples) {
    LMB_CHECK(s >= 0 && s < S, "learner state: tracked sample " << s << " of " << S);
  }
  LMB_CHECK(st.tracked_scores.size() == st.tracked_samples.size() * static_cast<size_t>(C1_),
            "learner state: " << st.tracked_scores.size() << " tracked scores for " << st.tracked_samples.size()
                              << " rows x " << C1_ << " classes");
  std::vector<int64_t> samples = st.entry_sample;
  std::vector<int32_t> codes = st.entry_code;
  std::vector<double> weights = st.entry_weight;
  rebuild_entry_index(samples, codes, weights);
  weight_exponent_ = st.weight_exponent;
  tracked_samples_ = st.tracked_samples;
  num_validation_rows_ = st.num_validation_rows;
  split_rows();
  pending_pool_.clear();
  tracked_scores_.resize(static_cast<size_t>(local_rows()) * C1_);
  for (int64_t i = 0; i < local_rows(); ++i) {
    const float* row = st.tracked_scores.data() + static_cast<size_t>(row_part_ + i * row_parts_) * C1_;
    std::copy(row, row + C1_, tracked_scores_.data() + static_cast<size_t>(i) * C1_);
  }
  class_offset_ = st.class_offset;
  negative_unit_ = st.negative_unit;
  model_ = st.model;
  last_validation_ = st.last_validation;
  initialized_ = true;
}

}  // namespace lmb
