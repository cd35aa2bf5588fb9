#include "train/boost/stump_search.h"

#include <algorithm>
#include <chrono>

#include "common/error.h"

namespace lmb {

namespace {
using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

bool by_dim_theta(const ScreenedCandidate& x, const ScreenedCandidate& y) {
  return x.dim != y.dim ? x.dim < y.dim : x.theta < y.theta;
}
}  // namespace

bool stump_better(const StumpRecord& x, const StumpRecord& y) {
  if (x.valid() != y.valid()) return x.valid();
  if (x.gain != y.gain) return x.gain > y.gain;
  if (x.dim != y.dim) return x.dim < y.dim;
  return x.theta < y.theta;
}

std::vector<ScreenedCandidate> best_candidates(std::vector<ScreenedCandidate> candidates, int32_t refine_top) {
  auto better = [](const ScreenedCandidate& x, const ScreenedCandidate& y) {
    if (x.gain != y.gain) return x.gain > y.gain;
    if (x.dim != y.dim) return x.dim < y.dim;
    return x.theta < y.theta;
  };
  const size_t keep = std::min(candidates.size(), static_cast<size_t>(std::max(refine_top, 0)));
  std::partial_sort(candidates.begin(), candidates.begin() + static_cast<int64_t>(keep), candidates.end(), better);
  candidates.resize(keep);
  return candidates;
}

StumpSearch::StumpSearch(const FeatureColumns& columns, const EntryStore& entries, const BoostOptions& options)
    : columns_(columns), entries_(entries), options_(options), screener_(entries) {}

SharingInput StumpSearch::threshold_input(int32_t t) {
  // Only classes with weight above the threshold can gain from sharing (for the others
  // g_c(alpha, beta) = -wm (beta - k_c)^2 <= 0), so the search sees those alone.
  const std::vector<int32_t>& touched = screener_.touched();
  const int32_t m = static_cast<int32_t>(touched.size());
  for (auto* v : {&wp_, &yp_, &wm_, &ym_}) v->resize(static_cast<size_t>(m));
  q_.resize(static_cast<size_t>(m));
  active_.resize(static_cast<size_t>(m));
  const int64_t* p = screener_.positive_above().data() + static_cast<size_t>(t) * m;
  const int64_t* n = screener_.negative_above().data() + static_cast<size_t>(t) * m;
  const std::vector<int64_t>& class_w = entries_.class_w();
  const std::vector<int64_t>& class_y = entries_.class_y();
  int32_t k = 0;
  for (int32_t j = 0; j < m; ++j) {
    const int64_t w = p[j] + n[j];
    const int32_t c = touched[j];
    const int64_t y = p[j] - n[j];
    active_[k] = c;
    wp_[k] = w;
    yp_[k] = y;
    wm_[k] = class_w[c] - w;
    ym_[k] = class_y[c] - y;
    q_[k] = entries_.class_q()[c];
    k += w > 0;
  }
  SharingInput in;
  in.num_classes = k;
  in.wp = wp_.data();
  in.yp = yp_.data();
  in.wm = wm_.data();
  in.ym = ym_.data();
  in.q = q_.data();
  return in;
}

StumpRecord StumpSearch::refine(int32_t dim, int32_t t, int32_t theta) {
  const SharingResult r = find_sharing_set(threshold_input(t), options_.sharing, &sharing_scratch_);
  StumpRecord rec;
  if (r.members.empty()) return rec;
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
}

StumpRecord StumpSearch::run(const std::vector<int32_t>& dims, const Select& select, double* pass_seconds) {
  StumpRecord best;
  auto consider = [&](StumpRecord rec) {
    if (rec.valid() && stump_better(rec, best)) best = std::move(rec);
  };
  std::vector<int32_t> sorted_dims = dims;
  std::sort(sorted_dims.begin(), sorted_dims.end());
  if (options_.screening.refine_top == 0) {
    for (int32_t d : sorted_dims) {
      const FeatureColumns::Ref ref = columns_.get(d, "search");
      const std::vector<uint8_t>& thresholds = ref.layout->thresholds;
      if (thresholds.empty()) continue;
      const auto t0 = Clock::now();
      screener_.collect_sums(ref);
      *pass_seconds += seconds_since(t0);
      for (size_t t = 0; t < thresholds.size(); ++t) consider(refine(d, static_cast<int32_t>(t), thresholds[t]));
    }
    return best;
  }
  std::vector<ScreenedCandidate> chosen =
      select(screener_.screen(columns_, sorted_dims, options_.screening.step, pass_seconds));
  std::sort(chosen.begin(), chosen.end(), by_dim_theta);
  FeatureColumns::Ref ref;
  for (const ScreenedCandidate& cand : chosen) {
    if (cand.dim != ref.dim) {
      ref = columns_.get(cand.dim, "refinement");
      screener_.collect_sums(ref);
    }
    const std::vector<uint8_t>& thresholds = ref.layout->thresholds;
    const auto it = std::find(thresholds.begin(), thresholds.end(), static_cast<uint8_t>(cand.theta));
    LMB_CHECK(it != thresholds.end(), "boost: threshold " << cand.theta << " is not a candidate of dim " << cand.dim);
    consider(refine(cand.dim, static_cast<int32_t>(it - thresholds.begin()), cand.theta));
  }
  return best;
}

std::vector<ScreenedCandidate> StumpSearch::screen(std::vector<int32_t> dims) {
  std::sort(dims.begin(), dims.end());
  double seconds = 0.0;
  std::vector<ScreenedCandidate> out = screener_.screen(columns_, dims, options_.screening.step, &seconds);
  std::sort(out.begin(), out.end(), by_dim_theta);
  return out;
}

}  // namespace lmb
