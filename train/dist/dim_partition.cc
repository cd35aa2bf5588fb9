#include "train/dist/dim_partition.h"

#include <algorithm>

#include "common/error.h"
#include "train/boost/column_screener.h"
#include "train/boost/feature_columns.h"

namespace lmb {

namespace {
bool by_dim(const ColumnMove& x, const ColumnMove& y) { return x.dim < y.dim; }
}  // namespace

std::vector<int32_t> rank_dims(int32_t num_dims, int rank, int size) {
  LMB_CHECK(size >= 1 && rank >= 0 && rank < size, "rank_dims: rank " << rank << " of " << size);
  std::vector<int32_t> dims;
  for (int32_t d = rank; d < num_dims; d += size) dims.push_back(d);
  return dims;
}

ScreeningPlan plan_screening(const std::vector<int32_t>& round_dims, const std::vector<uint8_t>& kind, int size) {
  ScreeningPlan plan;
  for (int32_t d : round_dims) plan.screener.emplace_back(d, dim_owner(d, size));
  if (size == 1) return plan;
  constexpr int64_t kBlock = ColumnScreener::kBlockDims;
  std::vector<std::vector<int32_t>> blocked(static_cast<size_t>(size));
  int64_t total = 0;
  for (int32_t d : round_dims) {
    if (kind[d] == FeatureColumns::kBlocked) {
      blocked[dim_owner(d, size)].push_back(d);
      ++total;
    }
  }
  const int64_t limit = kBlock * (((total + kBlock - 1) / kBlock + size - 1) / size);
  int to = 0;
  for (int from = 0; from < size; ++from) {
    while (static_cast<int64_t>(blocked[from].size()) > limit) {
      while (static_cast<int64_t>(blocked[to].size()) >= limit) ++to;  // exists: total <= size * limit
      const int32_t d = blocked[from].back();
      blocked[from].pop_back();
      blocked[to].push_back(d);
      plan.moves.push_back({d, from, to});
    }
  }
  std::sort(plan.moves.begin(), plan.moves.end(), by_dim);
  for (const ColumnMove& m : plan.moves) {
    for (auto& [d, r] : plan.screener) {
      if (d == m.dim) r = m.to;
    }
  }
  return plan;
}

RefinementPlan plan_refinement(const std::vector<ScreenedCandidate>& chosen, const ScreeningPlan& screening, int size) {
  struct DimCost {
    int32_t dim;
    double cost;
  };
  std::vector<DimCost> dims;
  for (const ScreenedCandidate& c : chosen) {
    auto it = std::find_if(dims.begin(), dims.end(), [&](const DimCost& d) { return d.dim == c.dim; });
    if (it == dims.end()) {
      // Measured at paper scale: a column pass costs ~3.3 sharing-set searches per unit of
      // above_fraction.
      dims.push_back({c.dim, 3.3 * c.above_fraction + 1.0});
    } else {
      it->cost += 1.0;
    }
  }
  std::sort(dims.begin(), dims.end(),
            [](const DimCost& x, const DimCost& y) { return x.cost != y.cost ? x.cost > y.cost : x.dim < y.dim; });
  auto screener = [&](int32_t dim) {
    for (const auto& [d, r] : screening.screener) {
      if (d == dim) return r;
    }
    return dim_owner(dim, size);
  };
  RefinementPlan plan;
  std::vector<double> load(static_cast<size_t>(size), 0.0);
  for (const DimCost& d : dims) {
    const int home = screener(d.dim);
    int best = home;
    for (int k = 0; k < size; ++k) {
      if (load[k] < load[best]) best = k;
    }
    load[best] += d.cost;
    plan.refiner.emplace_back(d.dim, best);
    if (best != home) plan.moves.push_back({d.dim, home, best});
  }
  std::sort(plan.moves.begin(), plan.moves.end(), by_dim);
  std::sort(plan.refiner.begin(), plan.refiner.end());
  return plan;
}

}  // namespace lmb
