#include "train/boost/screening_gain.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "common/random.h"
#include "train/boost/sharing_set.h"

namespace lmb {
namespace {

// Per-class sums of one threshold as the learner makes them: integer weights of +-1 entries, some
// classes with every entry on one side.
struct Classes {
  std::vector<double> wp, yp, wm, ym, q;
  size_t size() const { return wp.size(); }
};

Classes random_classes(Rng& rng, int m, int64_t max_weight) {
  Classes k;
  for (int c = 0; c < m; ++c) {
    int64_t p[2] = {0, 0}, n[2] = {0, 0};  // [above]
    const double above = rng.uniform() < 0.2 ? (rng.uniform() < 0.5 ? 0.0 : 1.0) : rng.uniform();
    const double positive = rng.uniform();
    const int entries = 1 + static_cast<int>(rng.below(12));
    for (int i = 0; i < entries; ++i) {
      const int64_t w = 1 + static_cast<int64_t>(rng.below(static_cast<uint64_t>(max_weight)));
      const int side = rng.uniform() < above ? 1 : 0;
      (rng.uniform() < positive ? p : n)[side] += w;
    }
    k.wp.push_back(static_cast<double>(p[1] + n[1]));
    k.yp.push_back(static_cast<double>(p[1] - n[1]));
    k.wm.push_back(static_cast<double>(p[0] + n[0]));
    k.ym.push_back(static_cast<double>(p[0] - n[0]));
    const double y = k.yp.back() + k.ym.back(), w = k.wp.back() + k.wm.back();
    k.q.push_back(y * y / w);
  }
  return k;
}

// The reference formulas, written out from the definitions (screening_gain.h's comment).
double reference_set_gain(const Classes& k, const std::vector<bool>& in) {
  double wp = 0, yp = 0, wm = 0, ym = 0, q = 0;
  for (size_t c = 0; c < k.size(); ++c) {
    if (!in[c]) continue;
    wp += k.wp[c], yp += k.yp[c], wm += k.wm[c], ym += k.ym[c], q += k.q[c];
  }
  double g = -q;
  if (wp > 0) g += yp * yp / wp;
  if (wm > 0) g += ym * ym / wm;
  return g;  // the terms in another order than the kernel's: equal up to rounding
}

void reference_point(const Classes& k, const std::vector<bool>& in, double* alpha, double* beta) {
  double wp = 0, yp = 0, wm = 0, ym = 0;
  for (size_t c = 0; c < k.size(); ++c) {
    if (in[c]) wp += k.wp[c], yp += k.yp[c], wm += k.wm[c], ym += k.ym[c];
  }
  *alpha = wp > 0 ? yp / wp : (wm > 0 ? ym / wm : 0.0);
  *beta = wm > 0 ? ym / wm : (wp > 0 ? yp / wp : 0.0);
}

// The screening gain straight from its definition: own points alpha_c = yp / wp, beta_c = ym / wm
// decide the rising and falling groups; the step sets are {c : g_c(alpha, beta) > 0}.
double reference_screening_gain(const Classes& k, bool step) {
  const size_t m = k.size();
  std::vector<bool> rise(m, false), fall(m, false);
  for (size_t c = 0; c < m; ++c) {
    if (k.wp[c] <= 0 || k.wm[c] <= 0) continue;  // an empty side: no own step
    const double alpha = k.yp[c] / k.wp[c], beta = k.ym[c] / k.wm[c];
    rise[c] = alpha > beta;
    fall[c] = alpha < beta;
  }
  double best = std::max(reference_set_gain(k, rise), reference_set_gain(k, fall));
  if (!step) return best;
  for (const std::vector<bool>* group : {&rise, &fall}) {
    double alpha, beta;
    reference_point(k, *group, &alpha, &beta);
    std::vector<bool> gains(m);
    for (size_t c = 0; c < m; ++c) {
      const double g =
          2 * alpha * k.yp[c] - alpha * alpha * k.wp[c] + 2 * beta * k.ym[c] - beta * beta * k.wm[c] - k.q[c];
      gains[c] = g > 0;
    }
    best = std::max(best, reference_set_gain(k, gains));
  }
  return best;
}

double kernel_screening_gain(const Classes& k, bool step) {
  return screening::screening_gain(
      [&](const auto& add) {
        for (size_t c = 0; c < k.size(); ++c) add(k.wp[c], k.yp[c], k.wm[c], k.ym[c], k.q[c]);
      },
      step);
}

TEST(ScreeningGain, SetGainIsTheSumOfTheMembersGainsAtTheFittedPoint) {
  // G(S) = sum over S of g_c(alpha, beta) at S's own point: what makes "the classes with
  // g_c > 0" the best set for a point, the step of the screening and of the full search.
  Rng rng(3);
  for (int trial = 0; trial < 200; ++trial) {
    const Classes k = random_classes(rng, 12, 1000);
    std::vector<bool> in(k.size());
    for (size_t c = 0; c < k.size(); ++c) in[c] = rng.uniform() < 0.5;
    double wp = 0, yp = 0, wm = 0, ym = 0, q = 0;
    for (size_t c = 0; c < k.size(); ++c) {
      if (in[c]) wp += k.wp[c], yp += k.yp[c], wm += k.wm[c], ym += k.ym[c], q += k.q[c];
    }
    if (wp <= 0 || wm <= 0) continue;
    double alpha, beta;
    screening::fit_point(wp, yp, wm, ym, &alpha, &beta);
    const screening::StepPoint point(alpha, beta);
    double sum = 0;
    for (size_t c = 0; c < k.size(); ++c) {
      if (in[c]) sum += point.a2 * k.yp[c] - point.aa * k.wp[c] + point.b2 * k.ym[c] - point.bb * k.wm[c] - k.q[c];
    }
    const double gain = screening::set_gain(wp, yp, wm, ym, q);
    EXPECT_NEAR(gain, sum, 1e-9 * (std::abs(gain) + wp + wm));
    EXPECT_NEAR(gain, reference_set_gain(k, in), 1e-12 * (std::abs(gain) + q));
  }
}

TEST(ScreeningGain, EqualsTheReferenceFormulaAndBoundsTheExhaustiveSearch) {
  Rng rng(5);
  for (int trial = 0; trial < 300; ++trial) {
    const Classes k = random_classes(rng, 1 + static_cast<int>(rng.below(11)), 1 << 20);
    for (bool step : {false, true}) {
      const double kernel = kernel_screening_gain(k, step);
      const double reference = reference_screening_gain(k, step);
      // The group decision by cross products (yp wm > ym wp) against the reference's quotients:
      // equal but for rounding at a tie, which these integer sums do not produce.
      EXPECT_NEAR(kernel, reference, 1e-9 * (std::abs(reference) + 1)) << "trial " << trial << " step " << step;
    }
    // A lower bound of the best set, which the step never lowers.
    double best = 0.0;
    const uint32_t m = static_cast<uint32_t>(k.size());
    for (uint32_t mask = 1; mask < (1u << m); ++mask) {
      std::vector<bool> in(m);
      for (uint32_t c = 0; c < m; ++c) in[c] = (mask >> c) & 1;
      best = std::max(best, reference_set_gain(k, in));
    }
    EXPECT_LE(kernel_screening_gain(k, true), best * (1 + 1e-12) + 1e-9);
    EXPECT_GE(kernel_screening_gain(k, true), kernel_screening_gain(k, false));
  }
}

TEST(ScreeningGain, SimdLanesEqualTheScalarGroupsBitForBit) {
  // Four thresholds in four lanes, classes added in the same order: every lane's sums equal the
  // scalar kernel's, bit for bit (integer sums below 2^52, as EntryStore::quantize guarantees).
  Rng rng(9);
  for (int trial = 0; trial < 50; ++trial) {
    const int m = 1 + static_cast<int>(rng.below(300));
    Classes lane[4];
    for (Classes& k : lane) k = random_classes(rng, m, int64_t{1} << 40);
    screening::Groups<screening::V4d> simd;
    screening::Groups<double> scalar[4];
    for (int c = 0; c < m; ++c) {
      screening::V4d f[5];
      for (int l = 0; l < 4; ++l) {
        f[0][l] = lane[l].wp[c], f[1][l] = lane[l].yp[c], f[2][l] = lane[l].wm[c], f[3][l] = lane[l].ym[c];
        f[4][l] = lane[l].q[c];
        scalar[l].add(lane[l].wp[c], lane[l].yp[c], lane[l].wm[c], lane[l].ym[c], lane[l].q[c]);
      }
      simd.add(f[0], f[1], f[2], f[3], f[4]);
    }
    for (int l = 0; l < 4; ++l) {
      for (int f = 0; f < 5; ++f) {
        EXPECT_EQ(simd.rise[f][l], scalar[l].rise[f]);
        EXPECT_EQ(simd.fall[f][l], scalar[l].fall[f]);
      }
      EXPECT_EQ(std::max(screening::gain_of(scalar[l].rise), screening::gain_of(scalar[l].fall)),
                kernel_screening_gain(lane[l], false));
    }
  }
}

TEST(ScreeningGain, SharingSetSearchScreeningUsesTheKernel) {
  // screen_sharing_gain (integer sums) equals the kernel on the same classes.
  Rng rng(13);
  for (int trial = 0; trial < 100; ++trial) {
    const Classes k = random_classes(rng, 1 + static_cast<int>(rng.below(40)), 1 << 24);
    std::vector<int64_t> wp, yp, wm, ym;
    for (size_t c = 0; c < k.size(); ++c) {
      wp.push_back(static_cast<int64_t>(k.wp[c]));
      yp.push_back(static_cast<int64_t>(k.yp[c]));
      wm.push_back(static_cast<int64_t>(k.wm[c]));
      ym.push_back(static_cast<int64_t>(k.ym[c]));
    }
    const SharingInput in{static_cast<int32_t>(k.size()), wp.data(), yp.data(), wm.data(), ym.data(), k.q.data()};
    EXPECT_EQ(screen_sharing_gain(in), kernel_screening_gain(k, true));
  }
}

}  // namespace
}  // namespace lmb
