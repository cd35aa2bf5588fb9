#include "train/boost/entry_store.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <numeric>

#include "common/error.h"

namespace lmb {

EntryStore::EntryStore(int64_t num_samples, int32_t num_classes_with_background)
    : num_samples_(num_samples), C1_(num_classes_with_background) {
  sample_offset_.assign(static_cast<size_t>(num_samples) + 1, 0);
  class_begin_.assign(static_cast<size_t>(C1_) + 1, 0);
  class_neg_begin_.assign(static_cast<size_t>(C1_), 0);
  class_sample_.assign(32, 0);
}

void EntryStore::assign(const std::vector<int64_t>& samples, const std::vector<int32_t>& codes,
                        const std::vector<double>& weights, int weight_exponent) {
  const int64_t S = num_samples_;
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
  code_.resize(E);
  weight_.resize(E);
  for (size_t i = 0; i < E; ++i) {
    const size_t j = order[i];
    code_[i] = codes[j];
    weight_[i] = weights[j];
    ++sample_offset_[samples[j] + 1];
  }
  for (int64_t s = 0; s < S; ++s) sample_offset_[s + 1] += sample_offset_[s];
  hot_.assign(E, HotEntry{0, 0, 0});
  for (size_t i = 0; i < E; ++i) hot_[i].code = code_[i];
  weight_exponent_ = weight_exponent;
  build_class_major();
}

void EntryStore::build_class_major() {
  const size_t E = code_.size();
  // Counting sort on the code (2 c + neg) keeps each group's samples ascending.
  std::vector<int64_t> code_begin(static_cast<size_t>(C1_) * 2 + 1, 0);
  for (size_t i = 0; i < E; ++i) ++code_begin[static_cast<size_t>(code_[i]) + 1];
  for (size_t i = 1; i < code_begin.size(); ++i) code_begin[i] += code_begin[i - 1];
  class_begin_.resize(static_cast<size_t>(C1_) + 1);
  class_neg_begin_.resize(static_cast<size_t>(C1_));
  for (int32_t c = 0; c < C1_; ++c) {
    class_begin_[c] = code_begin[2 * static_cast<size_t>(c)];
    class_neg_begin_[c] = code_begin[2 * static_cast<size_t>(c) + 1];
  }
  class_begin_[C1_] = code_begin.back();
  class_index_.resize(E);
  class_sample_.assign(E + 32, 0);  // padding: the blocked screening prefetches ahead
  class_wq_.assign(E, 0);
  for (int64_t s = 0; s < num_samples_; ++s) {
    for (int64_t e = sample_offset_[s]; e < sample_offset_[s + 1]; ++e) {
      const int64_t j = code_begin[static_cast<size_t>(code_[e])]++;
      class_index_[e] = j;
      class_sample_[j] = static_cast<int32_t>(s);
    }
  }
}

void EntryStore::append(const std::vector<int64_t>& new_samples, const std::vector<int32_t>& new_codes,
                        const std::vector<double>& new_weights) {
  if (new_samples.empty()) return;
  std::vector<int64_t> samples;
  std::vector<int32_t> codes;
  std::vector<double> weights;
  const size_t E = code_.size() + new_samples.size();
  samples.reserve(E);
  codes.reserve(E);
  weights.reserve(E);
  for (int64_t s = 0; s < num_samples_; ++s) {
    for (int64_t e = sample_offset_[s]; e < sample_offset_[s + 1]; ++e) {
      samples.push_back(s);
      codes.push_back(code_[e]);
      weights.push_back(weight_[e]);
    }
  }
  samples.insert(samples.end(), new_samples.begin(), new_samples.end());
  codes.insert(codes.end(), new_codes.begin(), new_codes.end());
  weights.insert(weights.end(), new_weights.begin(), new_weights.end());
  assign(samples, codes, weights, weight_exponent_);
}

void EntryStore::quantize(int32_t round) {
  double global_max = 0.0;
  for (double w : weight_) {
    LMB_CHECK(std::isfinite(w), "boost: a weight became non-finite at round " << round);
    global_max = std::max(global_max, w);
  }
  LMB_CHECK(global_max > 0.0, "boost: every entry weight is zero at round " << round);
  // Keep stored weights near 1: exact power-of-two rescaling.
  const int e = std::ilogb(global_max);
  if (e > 64 || e < -64) {
    for (double& w : weight_) w = std::ldexp(w, -e);
    weight_exponent_ += e;
    global_max = std::ldexp(global_max, -e);
  }
  const int bits = std::bit_width(static_cast<uint64_t>(weight_.size()) + 1);
  // Every quantised weight is < 2^(52 - bits), so any sum of entries is an integer below 2^52:
  // exact in a double too, which lets the screening convert and add sums in SIMD doubles without
  // rounding (order-free, like the int64 sums). The smallest weight kept is ~2^-32 of the largest
  // at 600,000 entries; a lighter one rounds to 0 and moves no gain by more than that fraction.
  const int shift = 52 - bits - (std::ilogb(global_max) + 1);
  LMB_CHECK(shift > -1000 && shift < 1000, "boost: weight scale 2^" << shift << " at round " << round);
  quant_shift_ = shift;
  class_w_.assign(static_cast<size_t>(C1_), 0);
  class_y_.assign(static_cast<size_t>(C1_), 0);
  const size_t E = weight_.size();
  // w * 2^shift is ldexp(w, shift) (a product with a normal power of two rounds like ldexp), and
  // for 0 <= x < 2^52 truncation plus a half-up step is llround(x): no libm call per entry.
  const double scale = std::ldexp(1.0, shift);
  for (size_t i = 0; i < E; ++i) {
    const double x = weight_[i] * scale;
    int64_t q = static_cast<int64_t>(x);
    q += x - static_cast<double>(q) >= 0.5;
    hot_[i].wq = q;
    class_wq_[class_index_[i]] = q;
    const int32_t c = code_[i] >> 1;
    class_w_[c] += q;
    class_y_[c] += (code_[i] & 1) ? -q : q;
  }
  class_q_.resize(static_cast<size_t>(C1_));
  for (int32_t c = 0; c < C1_; ++c) {
    const double y = static_cast<double>(class_y_[c]);
    class_q_[c] = class_w_[c] > 0 ? y * y / static_cast<double>(class_w_[c]) : 0.0;
  }
}

EntryStore::UpdateSums EntryStore::update(const std::vector<uint8_t>& above, const std::vector<uint8_t>& in_set,
                                          double alpha, double beta, const std::vector<double>& k) {
  // exp(-z h) takes few values: exp(-/+ alpha) and exp(-/+ beta) in the sharing set, exp(-/+ k_c)
  // outside it; tabulated once.
  std::vector<double> factor(static_cast<size_t>(C1_) * 2);  // [2 c + neg]: exp(-z k_c)
  for (int32_t c = 0; c < C1_; ++c) {
    factor[2 * c] = std::exp(-k[c]);
    factor[2 * c + 1] = std::exp(k[c]);
  }
  const double factor_above[2] = {std::exp(-alpha), std::exp(alpha)};
  const double factor_below[2] = {std::exp(-beta), std::exp(beta)};
  double squared_error = 0.0, cost = 0.0;
  for (int64_t s = 0; s < num_samples_; ++s) {
    const double h_in = above[s] ? alpha : beta;
    const double* f_in = above[s] ? factor_above : factor_below;
    for (int64_t e = sample_offset_[s]; e < sample_offset_[s + 1]; ++e) {
      const int32_t code = code_[e];
      const int32_t c = code >> 1;
      const double z = (code & 1) ? -1.0 : 1.0;
      const bool shared = in_set[c];
      const double h = shared ? h_in : k[c];
      const double w = weight_[e];
      squared_error += w * (z - h) * (z - h);
      const double nw = w * (shared ? f_in[code & 1] : factor[code]);
      weight_[e] = nw;
      cost += nw;
    }
  }
  const double scale = std::ldexp(1.0, weight_exponent_);
  return {squared_error * scale, cost * scale};
}

double EntryStore::exp_loss() const {
  double sum = 0.0;
  for (double w : weight_) sum += w;
  return sum * std::ldexp(1.0, weight_exponent_);
}

std::vector<EntryStore::Entry> EntryStore::entries() const {
  std::vector<Entry> out;
  out.reserve(weight_.size());
  const double scale = std::ldexp(1.0, weight_exponent_);
  for (int64_t s = 0; s < num_samples_; ++s) {
    for (int64_t e = sample_offset_[s]; e < sample_offset_[s + 1]; ++e) {
      out.push_back({s, code_[e] >> 1, static_cast<int8_t>((code_[e] & 1) ? -1 : 1), weight_[e] * scale});
    }
  }
  return out;
}

void EntryStore::save(LearnerState* st) const {
  st->entry_code = code_;
  st->entry_weight = weight_;
  st->entry_sample.clear();
  st->entry_sample.reserve(code_.size());
  for (int64_t s = 0; s < num_samples_; ++s) {
    for (int64_t e = sample_offset_[s]; e < sample_offset_[s + 1]; ++e) st->entry_sample.push_back(s);
  }
  st->weight_exponent = weight_exponent_;
}

void EntryStore::check(const LearnerState& st) const {
  const size_t E = st.entry_sample.size();
  LMB_CHECK(st.entry_code.size() == E && st.entry_weight.size() == E,
            "learner state: " << E << " entry samples but " << st.entry_code.size() << " codes and "
                              << st.entry_weight.size() << " weights");
  for (size_t i = 0; i < E; ++i) {
    LMB_CHECK(st.entry_sample[i] >= 0 && st.entry_sample[i] < num_samples_,
              "learner state: entry " << i << " has sample " << st.entry_sample[i] << " of " << num_samples_);
    LMB_CHECK(st.entry_code[i] >= 0 && (st.entry_code[i] >> 1) < C1_,
              "learner state: entry " << i << " has class " << (st.entry_code[i] >> 1) << " of " << C1_);
    LMB_CHECK(std::isfinite(st.entry_weight[i]) && st.entry_weight[i] >= 0.0,
              "learner state: entry " << i << " has weight " << st.entry_weight[i]);
    LMB_CHECK(i == 0 || st.entry_sample[i - 1] < st.entry_sample[i] ||
                  (st.entry_sample[i - 1] == st.entry_sample[i] && st.entry_code[i - 1] < st.entry_code[i]),
              "learner state: entries are not in (sample, code) order at " << i);
  }
}

void EntryStore::restore(const LearnerState& st) {
  assign(st.entry_sample, st.entry_code, st.entry_weight, st.weight_exponent);
}

}  // namespace lmb
