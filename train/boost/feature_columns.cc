#include "train/boost/feature_columns.h"

#include <algorithm>
#include <cstring>

#include "common/error.h"

namespace lmb {

FeatureColumns::FeatureColumns(const FeatureMatrix& features, const ScreeningOptions& options)
    : features_(features), options_(options) {
  global_to_stored_.assign(static_cast<size_t>(features.num_dims), -1);
  for (int32_t i = 0; i < features.num_stored_columns(); ++i) {
    const int32_t d = features.dims.empty() ? i : features.dims[i];
    LMB_CHECK(d >= 0 && d < features.num_dims, "features: stored column " << i << " has dim " << d);
    global_to_stored_[d] = i;
  }
  const int32_t n = features.num_stored_columns();
  layouts_.resize(static_cast<size_t>(n));
  int32_t num_usable = 0;
  for (int32_t i = 0; i < n; ++i) {
    layouts_[i] = make_layout(features.column(i));
    num_usable += !layouts_[i].thresholds.empty();
  }
  LMB_CHECK(n == 0 || num_usable > 0, "features: all " << n << " stored columns are constant; no stump can split them");
}

void FeatureColumns::fill_buckets(Layout* layout) {
  size_t t = 0;
  for (int v = 0; v < 256; ++v) {
    while (t < layout->thresholds.size() && layout->thresholds[t] < v) ++t;
    layout->bucket[v] = static_cast<uint8_t>(t);
  }
}

FeatureColumns::Layout FeatureColumns::make_layout(const uint8_t* col) const {
  const int32_t max_t = options_.max_thresholds;
  int64_t counts[256] = {0};
  for (int64_t s = 0; s < features_.num_samples; ++s) ++counts[col[s]];
  std::vector<uint8_t> distinct;
  for (int v = 0; v < 256; ++v) {
    if (counts[v]) distinct.push_back(static_cast<uint8_t>(v));
  }
  Layout layout;
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
  layout.above_fraction =
      features_.num_samples > 0
          ? static_cast<float>(static_cast<double>(above) / static_cast<double>(features_.num_samples))
          : 0.f;
  return layout;
}

FeatureColumns::Ref FeatureColumns::find(int32_t dim) const {
  const int32_t stored = stored_index(dim);
  if (stored >= 0) return {dim, features_.column(stored), &layouts_[stored]};
  for (const Lent& lent : lent_) {
    if (lent.dim == dim) return {dim, lent.column.data(), &lent.layout};
  }
  return {};
}

FeatureColumns::Ref FeatureColumns::get(int32_t dim, const char* what) const {
  const Ref ref = find(dim);
  LMB_CHECK(ref.column, "boost: " << what << ": dim " << dim << " is neither stored nor lent here");
  return ref;
}

FeatureColumns::Kind FeatureColumns::kind(const Layout& layout) const {
  const size_t T = layout.thresholds.size();
  if (T == 0) return kConstant;
  return T <= kMaxBlockedThresholds && options_.blocked && !options_.step ? kBlocked : kColumnPass;
}

void FeatureColumns::above(int32_t dim, int32_t theta, std::vector<uint8_t>* above) const {
  const uint8_t* col = get(dim, "stump").column;
  above->resize(static_cast<size_t>(features_.num_samples));
  for (int64_t s = 0; s < features_.num_samples; ++s) (*above)[s] = col[s] > theta;
}

// Packed: S bins, the above fraction (float), the thresholds, their count (one byte, last).
std::vector<uint8_t> FeatureColumns::pack(int32_t dim) const {
  const Ref ref = get(dim, "lend");
  const size_t S = static_cast<size_t>(features_.num_samples);
  const std::vector<uint8_t>& t = ref.layout->thresholds;
  std::vector<uint8_t> packed(S + sizeof(float) + t.size() + 1);
  std::memcpy(packed.data(), ref.column, S);
  std::memcpy(packed.data() + S, &ref.layout->above_fraction, sizeof(float));
  std::copy(t.begin(), t.end(), packed.begin() + static_cast<int64_t>(S + sizeof(float)));
  packed.back() = static_cast<uint8_t>(t.size());
  return packed;
}

void FeatureColumns::lend(int32_t dim, std::vector<uint8_t> packed) {
  const size_t S = static_cast<size_t>(features_.num_samples);
  const size_t T = packed.empty() ? 0 : packed.back();
  LMB_CHECK(dim >= 0 && dim < features_.num_dims && packed.size() == S + sizeof(float) + T + 1,
            "boost: a lent column of dim " << dim << " has " << packed.size() << " bytes for " << S << " samples");
  if (find(dim).column) return;
  Lent lent{dim, {}, {}};
  lent.layout.thresholds.assign(packed.begin() + static_cast<int64_t>(S + sizeof(float)), packed.end() - 1);
  std::memcpy(&lent.layout.above_fraction, packed.data() + S, sizeof(float));
  LMB_CHECK(std::is_sorted(lent.layout.thresholds.begin(), lent.layout.thresholds.end()) &&
                std::adjacent_find(lent.layout.thresholds.begin(), lent.layout.thresholds.end()) ==
                    lent.layout.thresholds.end(),
            "boost: a lent column of dim " << dim << " has unordered thresholds");
  fill_buckets(&lent.layout);
  packed.resize(S);
  lent.column = std::move(packed);
  lent_.push_back(std::move(lent));
}

}  // namespace lmb
