// Who does what of a round in the feature-parallel learner (train/dist/feature_parallel_learner.h):
// which rank owns a dim, and how the round's screening and refinement are balanced by lending
// columns between ranks. Pure functions of the round's data: every rank computes the same plan.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "train/boost/stump_record.h"

namespace lmb {

// Dim d belongs to rank d % size (round-robin, so each rank gets about |F_m| / size of every
// round's random draw, context dims and descriptor bits alike).
inline int dim_owner(int32_t dim, int size) { return dim % size; }
// The dims rank `rank` of `size` owns, ascending.
std::vector<int32_t> rank_dims(int32_t num_dims, int rank, int size);

// A column (S bytes) that rank `from` lends to rank `to` for the round.
struct ColumnMove {
  int32_t dim;
  int from, to;
};

// The screening plan of a round: the blocked screening costs one class-major pass per
// ColumnScreener::kBlockDims dims, so a rank's cost is ceil(n / kBlockDims) passes for its n
// blocked dims (kind[d] == FeatureColumns::kBlocked). Ranks above the least possible maximum,
// kBlockDims ceil(ceil(N / kBlockDims) / size) dims, lend their highest blocked dims to the ranks
// below it. Returns (dim, screening rank) for every round dim, in round order, and the moves by
// ascending dim.
struct ScreeningPlan {
  std::vector<std::pair<int32_t, int>> screener;
  std::vector<ColumnMove> moves;
};
ScreeningPlan plan_screening(const std::vector<int32_t>& round_dims, const std::vector<uint8_t>& kind, int size);

// The refinement plan of the globally chosen candidates: a candidate dim costs a column pass (its
// entries above the smallest threshold) plus a sharing-set search per candidate threshold; dims
// go, most expensive first, to the least loaded rank (on a tie the rank that screened it, which
// has the column). Returns (dim, refining rank) by ascending dim, and the moves (from the
// screening rank) by ascending dim.
struct RefinementPlan {
  std::vector<std::pair<int32_t, int>> refiner;
  std::vector<ColumnMove> moves;
};
RefinementPlan plan_refinement(const std::vector<ScreenedCandidate>& chosen, const ScreeningPlan& screening, int size);

}  // namespace lmb
