// The small records a round's search passes around and a distributed layer exchanges: screened
// (dim, threshold) candidates and the best stump found.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

namespace lmb {

// The best stump of a search (of a rank, before the ranks agree on one).
struct StumpRecord {
  double gain = -std::numeric_limits<double>::infinity();  // G(S) in weight units; higher is better
  int32_t dim = -1;                                        // global dim, -1 = none
  int32_t theta = 0;                                       // threshold bin
  std::vector<int32_t> classes;                            // sharing set, ascending class ids
  int64_t wp = 0, yp = 0, wm = 0, ym = 0;                  // fixed-point sums over S
  bool valid() const { return dim >= 0; }
};
// Strict order: larger gain, then smaller dim, then smaller theta.
bool stump_better(const StumpRecord& x, const StumpRecord& y);

// A (dim, threshold) after the cheap screening search.
struct ScreenedCandidate {
  double gain = 0.0;
  int32_t dim = -1;
  int32_t theta = 0;
  float above_fraction = 0.f;  // the dim's samples above its smallest threshold (refinement cost)
};
// The refine_top best of `candidates` by (larger gain, smaller dim, smaller theta), in that order.
std::vector<ScreenedCandidate> best_candidates(std::vector<ScreenedCandidate> candidates, int32_t refine_top);

}  // namespace lmb
