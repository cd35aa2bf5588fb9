// The sharing-set search of one candidate (dimension f, threshold theta).
//
// Per active class c the caller gives the weight sums of its entries (positives z = +1 and its
// own negatives z = -1) above and below the threshold, in fixed-point weight units:
//   wp_c = sum w [v > theta],  yp_c = sum w z [v > theta],  wm_c, ym_c likewise for v <= theta,
// and q_c = (yp_c + ym_c)^2 / (wp_c + wm_c), the error reduction of the class's own constant k_c.
// The stump's squared error J is minimal when the gain
//   G(S) = Yp_S^2 / Wp_S + Ym_S^2 / Wm_S - sum_{c in S} q_c     (Yp_S = sum_{c in S} yp_c, ...)
// is maximal; then a + b = Yp_S / Wp_S and b = Ym_S / Wm_S.
//
// Equivalently, G(S) with its fitted (alpha, beta) = (a + b, b) is the sum over S of
//   g_c(alpha, beta) = 2 alpha yp_c - alpha^2 wp_c + 2 beta ym_c - beta^2 wm_c - q_c,
// so the best set for a given (alpha, beta) is {c : g_c(alpha, beta) > 0} and the search is the
// maximisation over the plane of sum_c max(0, g_c(alpha, beta)). find_sharing_set alternates
// "set from point" and "point from set" (each step never lowers G, so it stops at a fixed point)
// from several starts: the "rising" classes (own alpha_c > beta_c: mass above the threshold looks
// positive), the "falling" classes, and the own points of the best single classes. This replaces
// Torralba's greedy O(C^2) forward selection by a few O(C) passes; see the tests for its
// exactness against exhaustive search and its ratio to the greedy search.
#pragma once

#include <cstdint>
#include <vector>

namespace lmb {

struct SharingInput {
  int32_t num_classes = 0;  // m active classes; arrays below have m entries
  const int64_t* wp = nullptr;
  const int64_t* yp = nullptr;
  const int64_t* wm = nullptr;
  const int64_t* ym = nullptr;
  const double* q = nullptr;
};

struct SharingSearchOptions {
  int32_t single_starts = 4;    // starts at the own points of the best single classes
  int32_t max_iterations = 12;  // alternation steps per start
  bool group_starts = true;     // the "rising" and "falling" group starts
};

struct SharingResult {
  double gain = 0.0;                       // G(S) in weight units (0 for the empty set)
  std::vector<int32_t> members;            // indices into the input arrays, ascending
  int64_t wp = 0, yp = 0, wm = 0, ym = 0;  // sums over the members
};

// G(S) of a member set given its sums; `sum_q` = sum of q over the members.
double sharing_gain(int64_t wp, int64_t yp, int64_t wm, int64_t ym, double sum_q);

// Best set found from the starts. Deterministic: fixed start order, ties keep the earlier start.
// `scratch` is reused between calls to avoid allocation (may be empty).
SharingResult find_sharing_set(const SharingInput& input, const SharingSearchOptions& options,
                               std::vector<uint8_t>* scratch = nullptr);

// Cheap screening estimate of the best gain (train/boost/screening_gain.h): the rising and
// falling groups and one alternation step from each. A lower bound of what find_sharing_set with
// group starts returns; the learner ranks (dim, theta) candidates by it before the full search.
double screen_sharing_gain(const SharingInput& input);

}  // namespace lmb
