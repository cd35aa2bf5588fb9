#include "train/boost/sharing_set.h"

#include <gtest/gtest.h>

#include "common/random.h"

namespace lmb {
namespace {

struct Problem {
  std::vector<int64_t> wp, yp, wm, ym;
  std::vector<double> q;
  SharingInput input() const {
    return {static_cast<int32_t>(wp.size()), wp.data(), yp.data(), wm.data(), ym.data(), q.data()};
  }
};

// Random per-class sums from a few weighted +-1 entries split by a threshold.
Problem random_problem(Rng& rng, int m) {
  Problem p;
  for (int c = 0; c < m; ++c) {
    int64_t wp = 0, yp = 0, wm = 0, ym = 0;
    const double bias = rng.uniform();
    const double above = rng.uniform();
    const int n = 2 + static_cast<int>(rng.below(10));
    for (int i = 0; i < n; ++i) {
      const int64_t w = 1 + static_cast<int64_t>(rng.below(1000000));
      const int64_t z = rng.uniform() < bias ? 1 : -1;
      if (rng.uniform() < above) {
        wp += w;
        yp += z * w;
      } else {
        wm += w;
        ym += z * w;
      }
    }
    p.wp.push_back(wp);
    p.yp.push_back(yp);
    p.wm.push_back(wm);
    p.ym.push_back(ym);
    const double y = static_cast<double>(yp + ym);
    p.q.push_back(y * y / static_cast<double>(wp + wm));
  }
  return p;
}

double best_exhaustive(const Problem& p) {
  const int m = static_cast<int>(p.wp.size());
  double best = 0.0;
  for (uint32_t mask = 1; mask < (1u << m); ++mask) {
    int64_t wp = 0, yp = 0, wm = 0, ym = 0;
    double q = 0;
    for (int c = 0; c < m; ++c) {
      if (mask & (1u << c)) {
        wp += p.wp[c];
        yp += p.yp[c];
        wm += p.wm[c];
        ym += p.ym[c];
        q += p.q[c];
      }
    }
    best = std::max(best, sharing_gain(wp, yp, wm, ym, q));
  }
  return best;
}

TEST(SharingSet, MatchesExhaustiveSearchOnSmallProblems) {
  Rng rng(3);
  int exact = 0, trials = 400;
  double worst = 1.0;
  for (int t = 0; t < trials; ++t) {
    const Problem p = random_problem(rng, 2 + static_cast<int>(rng.below(9)));
    const double ref = best_exhaustive(p);
    SharingSearchOptions o;
    o.single_starts = 10;
    const SharingResult r = find_sharing_set(p.input(), o);
    // The reported gain is the gain of the reported set.
    int64_t wp = 0, yp = 0, wm = 0, ym = 0;
    double q = 0;
    for (int32_t i : r.members) {
      wp += p.wp[i];
      yp += p.yp[i];
      wm += p.wm[i];
      ym += p.ym[i];
      q += p.q[i];
    }
    EXPECT_EQ(wp, r.wp);
    EXPECT_NEAR(sharing_gain(wp, yp, wm, ym, q), r.gain, 1e-9 * std::max(1.0, ref));
    EXPECT_LE(r.gain, ref * (1 + 1e-12) + 1e-9);
    if (r.gain >= ref * (1 - 1e-9)) ++exact;
    if (ref > 0) worst = std::min(worst, r.gain / ref);
    // Screening never claims more than the full search.
    EXPECT_LE(screen_sharing_gain(p.input()), ref * (1 + 1e-12) + 1e-9);
  }
  std::printf("sharing search: exhaustive optimum reached on %d/%d random problems, worst ratio %.6f\n", exact, trials,
              worst);
  EXPECT_EQ(exact, trials);
}

TEST(SharingSet, EmptyAndDegenerateInputs) {
  Problem p;
  EXPECT_EQ(find_sharing_set(p.input(), {}).members.size(), 0u);
  // One class, all mass above: no step to share, no gain.
  p.wp = {10};
  p.yp = {4};
  p.wm = {0};
  p.ym = {0};
  p.q = {1.6};
  const SharingResult r = find_sharing_set(p.input(), {});
  EXPECT_TRUE(r.members.empty());
  EXPECT_EQ(r.gain, 0.0);
}

}  // namespace
}  // namespace lmb
