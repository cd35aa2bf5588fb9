// ransac<Estimator> with mock estimators (2D lines): the stopping rules against their formulas,
// PROSAC's sampling schedule, local optimisation, the runner-up, determinism and the options.
#include "infer/ransac.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Core>

#include "common/error.h"
#include "common/random.h"

namespace lmb {
namespace {

struct Line {
  double a = 0.0;  // y = a x + b
  double b = 0.0;
};

// A mock estimator: points (x, y), lines through two of them, residual |y - a x - b|.
class LineEstimator {
 public:
  using Model = Line;
  static constexpr int kSampleSize = 2;

  LineEstimator(std::vector<Eigen::Vector2d> points, double threshold)
      : points_(std::move(points)), threshold_(threshold) {}

  int num_data() const { return static_cast<int>(points_.size()); }

  void generate_models(const int* sample, std::vector<Line>* models) {
    ++solver_calls;
    samples.emplace_back(sample[0], sample[1]);
    const Eigen::Vector2d& p = points_[sample[0]];
    const Eigen::Vector2d& q = points_[sample[1]];
    if (std::abs(q.x() - p.x()) < 1e-12) return;
    Line l;
    l.a = (q.y() - p.y()) / (q.x() - p.x());
    l.b = p.y() - l.a * p.x();
    models->push_back(l);
  }

  double residual(const Line& l, int i) const { return std::abs(points_[i].y() - l.a * points_[i].x() - l.b); }

  double score(const Line& l, int* num_inliers) const {
    double cost = 0.0;
    int inliers = 0;
    for (int i = 0; i < num_data(); ++i) {
      const double r = residual(l, i);
      inliers += r < threshold_;
      cost += std::min(r, threshold_);
    }
    *num_inliers = inliers;
    return cost;
  }

  void inliers(const Line& l, std::vector<char>* mask) const {
    mask->resize(points_.size());
    for (int i = 0; i < num_data(); ++i) (*mask)[i] = residual(l, i) < threshold_;
  }

  // Least squares on the inliers.
  void refine(Line* l, bool /*final*/) const {
    ++refine_calls;
    if (!refine_enabled) return;
    double sx = 0, sy = 0, sxx = 0, sxy = 0, n = 0;
    for (int i = 0; i < num_data(); ++i) {
      if (residual(*l, i) >= threshold_) continue;
      const double x = points_[i].x(), y = points_[i].y();
      sx += x, sy += y, sxx += x * x, sxy += x * y, n += 1;
    }
    const double det = n * sxx - sx * sx;
    if (n < 2 || std::abs(det) < 1e-12) return;
    l->a = (n * sxy - sx * sy) / det;
    l->b = (sy - l->a * sx) / n;
  }

  bool refine_enabled = true;
  int solver_calls = 0;
  mutable int refine_calls = 0;
  std::vector<std::pair<int, int>> samples;

 private:
  std::vector<Eigen::Vector2d> points_;
  double threshold_;
};

struct LineData {
  std::vector<Eigen::Vector2d> points;
  std::vector<char> on_line;  // 1 = on line A, 2 = on line B, 0 = random
};

// n points: num_a on y = 0.5 x + 1, num_b on y = -2 x + 30, the rest uniform in [0, 100]^2, with
// Gaussian noise sigma on the line points; shuffled unless `sorted` (line A first, then B, then
// the rest).
LineData make_lines(uint64_t seed, int n, int num_a, int num_b, double sigma, bool sorted = false) {
  Rng rng(seed);
  LineData d;
  for (int i = 0; i < n; ++i) {
    const double x = rng.uniform(0, 100);
    if (i < num_a) {
      d.points.emplace_back(x, 0.5 * x + 1 + sigma * rng.normal());
      d.on_line.push_back(1);
    } else if (i < num_a + num_b) {
      d.points.emplace_back(x, -2 * x + 30 + sigma * rng.normal());
      d.on_line.push_back(2);
    } else {
      d.points.emplace_back(x, rng.uniform(-100, 100));
      d.on_line.push_back(0);
    }
  }
  if (!sorted) {
    std::vector<int> order(n);
    for (int i = 0; i < n; ++i) order[i] = i;
    rng.shuffle(order);
    LineData s;
    for (int i : order) {
      s.points.push_back(d.points[i]);
      s.on_line.push_back(d.on_line[i]);
    }
    return s;
  }
  return d;
}

// Points within `threshold` of y = a x + b: the line's points and random ones that fall near it.
int count_near(const LineData& d, double a, double b, double threshold) {
  int n = 0;
  for (const Eigen::Vector2d& p : d.points) n += std::abs(p.y() - a * p.x() - b) < threshold;
  return n;
}

RansacOptions uniform_options(uint64_t seed, int max_iterations = 10000) {
  RansacOptions o;
  o.progressive = false;
  o.seed = seed;
  o.max_iterations = max_iterations;
  return o;
}

TEST(Ransac, UniformFindsTheLineAndStopsAtTheRansacBound) {
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    const LineData d = make_lines(seed, 200, 60, 0, 0.0);
    LineEstimator e(d.points, 0.5);
    Line best;
    const RansacOptions o = uniform_options(seed);
    const RansacStats s = ransac(e, o, &best);
    EXPECT_NEAR(best.a, 0.5, 1e-9);
    EXPECT_NEAR(best.b, 1.0, 1e-7);
    const int inliers = count_near(d, 0.5, 1.0, 0.5);  // 60 + a random point or two
    ASSERT_GE(inliers, 60);
    EXPECT_EQ(s.num_inliers, inliers);
    EXPECT_DOUBLE_EQ(s.inlier_ratio, inliers / 200.0);
    // Stopped by the bound of the whole set: k = log(1 - p) / log(1 - I (I - 1) / (200 * 199)).
    const double k = std::log(1 - o.success_probability) / std::log(1 - inliers * (inliers - 1.0) / (200.0 * 199));
    EXPECT_EQ(s.stop_subset, 200);
    EXPECT_EQ(s.iterations, static_cast<int>(std::ceil(k))) << "seed " << seed;
    EXPECT_EQ(s.subset_size, 200);
    EXPECT_EQ(e.solver_calls, s.iterations);
  }
}

TEST(Ransac, ProsacWithAPerfectOrderNeedsAHandfulOfIterations) {
  // 10 % inliers, all ranked first: PROSAC's first sample is two of them; LO then finds every
  // inlier and the top subsets make the search stop. Uniform sampling needs hundreds of samples.
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    const LineData d = make_lines(seed, 500, 50, 0, 0.0, /*sorted=*/true);
    LineEstimator e(d.points, 0.5);
    RansacOptions o;
    o.seed = seed;
    o.max_iterations = 10000;
    o.min_support = 12;
    Line best;
    const RansacStats s = ransac(e, o, &best);
    EXPECT_NEAR(best.a, 0.5, 1e-9);
    const int inliers = count_near(d, 0.5, 1.0, 0.5);
    EXPECT_EQ(s.num_inliers, inliers);
    EXPECT_LE(s.iterations, 3) << "seed " << seed;
    EXPECT_GT(s.stop_subset, 0);
    EXPECT_LE(s.stop_subset, 50);
    EXPECT_EQ(e.samples.front(), std::make_pair(0, 1));  // the top two

    LineEstimator uniform(d.points, 0.5);
    const RansacStats su = ransac(uniform, uniform_options(seed), &best);
    EXPECT_EQ(su.num_inliers, inliers);
    EXPECT_GT(su.iterations, 500);
  }
}

TEST(Ransac, ProsacBeatsUniformWithAnInformativeOrder) {
  // 10 % inliers; the order is a noisy score (inliers ~ N(1.5, 1), others ~ N(0, 1)). At 50
  // samples PROSAC finds the line on every seed; uniform sampling (1 % of its samples are
  // all-inlier: 39 % of the searches succeed) on few.
  int prosac_found = 0, uniform_found = 0;
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    const LineData raw = make_lines(seed, 400, 40, 0, 0.1);
    Rng rng(seed + 1000);
    std::vector<std::pair<double, int>> ranked;
    for (size_t i = 0; i < raw.points.size(); ++i) {
      ranked.emplace_back((raw.on_line[i] ? 1.5 : 0.0) + rng.normal(), static_cast<int>(i));
    }
    std::sort(ranked.begin(), ranked.end(), [](auto& x, auto& y) { return x.first > y.first; });
    std::vector<Eigen::Vector2d> sorted;
    for (auto& [q, i] : ranked) sorted.push_back(raw.points[i]);
    Line best;
    LineEstimator p(sorted, 0.5);
    RansacOptions o;
    o.seed = seed;
    o.max_iterations = 50;
    const RansacStats sp = ransac(p, o, &best);
    prosac_found += sp.num_inliers >= 38 && std::abs(best.a - 0.5) < 0.01;
    LineEstimator u(sorted, 0.5);
    const RansacStats su = ransac(u, uniform_options(seed, 50), &best);
    uniform_found += su.num_inliers >= 38 && std::abs(best.a - 0.5) < 0.01;
  }
  EXPECT_EQ(prosac_found, 20);
  EXPECT_LT(uniform_found, 16);
}

TEST(Ransac, LocalOptimisationImprovesOnTheMinimalModels) {
  const LineData d = make_lines(3, 300, 150, 0, 0.3);
  Line refined, minimal;
  LineEstimator with(d.points, 1.0);
  const RansacStats a = ransac(with, uniform_options(4), &refined);
  LineEstimator without(d.points, 1.0);
  without.refine_enabled = false;
  const RansacStats b = ransac(without, uniform_options(4), &minimal);
  EXPECT_GE(a.refinements, 1);
  EXPECT_EQ(a.refinements, with.refine_calls);
  EXPECT_LT(a.score, b.score);
  EXPECT_LT(std::abs(refined.a - 0.5), std::abs(minimal.a - 0.5) + 1e-12);
}

TEST(Ransac, RunnerUpIsTheSecondLine) {
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    const LineData d = make_lines(seed, 300, 90, 60, 0.0);
    LineEstimator e(d.points, 0.5);
    Line best, second;
    RansacOptions o = uniform_options(seed, 400);
    o.min_iterations = 400;  // line B's samples (4 % of them) are met for sure
    const RansacStats s = ransac(e, o, &best, &second);
    EXPECT_NEAR(best.a, 0.5, 1e-9);
    ASSERT_GT(s.runner_up_inliers, 0);
    EXPECT_NEAR(second.a, -2.0, 1e-9);
    EXPECT_EQ(s.runner_up_inliers, count_near(d, -2.0, 30.0, 0.5));
    EXPECT_LE(s.runner_up_shared, 2);  // the lines cross: a point or two near the crossing
    EXPECT_LT(s.score, s.runner_up_score);
  }
  // One line only: no runner-up beyond chance alignments of the random points.
  const LineData one = make_lines(9, 300, 90, 0, 0.0);
  LineEstimator e(one.points, 0.5);
  Line best;
  const RansacStats s = ransac(e, uniform_options(9, 400), &best);
  EXPECT_LT(s.runner_up_inliers, 12);
}

TEST(Ransac, SameSeedSameResultOtherSeedOtherSamples) {
  const LineData d = make_lines(5, 300, 60, 30, 0.2);
  LineEstimator a(d.points, 0.5), b(d.points, 0.5), c(d.points, 0.5);
  Line la, lb, lc;
  RansacOptions o;
  o.seed = 11;
  const RansacStats sa = ransac(a, o, &la);
  const RansacStats sb = ransac(b, o, &lb);
  EXPECT_EQ(a.samples, b.samples);
  EXPECT_EQ(sa.iterations, sb.iterations);
  EXPECT_EQ(la.a, lb.a);
  EXPECT_EQ(la.b, lb.b);
  o.seed = 12;
  ransac(c, o, &lc);
  EXPECT_NE(a.samples, c.samples);
}

TEST(Ransac, IterationLimits) {
  const LineData d = make_lines(6, 300, 20, 0, 0.0);  // 6.7 %: the bound is far above these caps
  for (int cap : {1, 2, 7, 50}) {
    LineEstimator e(d.points, 0.5);
    Line best;
    const RansacStats s = ransac(e, uniform_options(1, cap), &best);
    EXPECT_EQ(s.iterations, cap);
    EXPECT_EQ(s.stop_subset, 0);
  }
  // min_iterations holds the search although every subset is satisfied at once.
  const LineData all = make_lines(7, 100, 100, 0, 0.0);
  LineEstimator e(all.points, 0.5);
  RansacOptions o;
  o.min_iterations = 40;
  o.max_iterations = 100;
  Line best;
  EXPECT_EQ(ransac(e, o, &best).iterations, 40);
  // Fewer data than a sample: nothing.
  LineEstimator tiny(std::vector<Eigen::Vector2d>{{1, 1}}, 0.5);
  const RansacStats s = ransac(tiny, o, &best);
  EXPECT_EQ(s.iterations, 0);
  EXPECT_EQ(s.num_inliers, 0);
}

TEST(ProsacSampler, FollowsTheGrowthSchedule) {
  const int N = 1000, m = 3;
  ProsacSampler sampler(N, m, true, 200000.0, 1);
  // The schedule T'_n recomputed here from its definition.
  std::vector<double> grow(N + 1, 0.0);
  double t_n = 200000.0;
  for (int i = 0; i < m; ++i) t_n *= static_cast<double>(m - i) / (N - i);
  double tp = 1.0;
  for (int n = m; n < N; ++n) {
    grow[n] = tp;
    const double next = t_n * (n + 1.0) / (n + 1.0 - m);
    tp += std::ceil(next - t_n);
    t_n = next;
  }
  int n = m, previous = m;
  int sample[m];
  for (int t = 1; t <= 3000; ++t) {
    while (n < N && t > grow[n]) ++n;
    sampler.draw(sample);
    ASSERT_EQ(sampler.subset_size(), n) << "t " << t;
    ASSERT_GE(n, previous);
    previous = n;
    std::set<int> distinct(sample, sample + m);
    ASSERT_EQ(distinct.size(), static_cast<size_t>(m));
    // The newest datum of U_n plus m - 1 of U_{n-1}.
    ASSERT_EQ(sample[m - 1], n - 1);
    for (int k = 0; k < m - 1; ++k) ASSERT_LT(sample[k], n - 1);
    ASSERT_EQ(sampler.samples_within(n), t);
  }
  EXPECT_GT(n, 100);
  EXPECT_LT(n, N);
}

TEST(ProsacSampler, UniformCoversEveryDatum) {
  ProsacSampler sampler(20, 3, false, 1.0, 2);
  std::vector<int> hits(20, 0);
  int sample[3];
  for (int t = 0; t < 2000; ++t) {
    sampler.draw(sample);
    for (int k : sample) ++hits[k];
  }
  for (int h : hits) EXPECT_GT(h, 200);  // 300 expected each
  EXPECT_EQ(sampler.subset_size(), 20);
}

TEST(RansacOptions, CheckRejectsOutOfRangeValues) {
  EXPECT_NO_THROW(RansacOptions().check());
  auto rejects = [](auto mutate, const char* field) {
    RansacOptions o;
    mutate(o);
    try {
      o.check();
      ADD_FAILURE() << field << " accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  rejects([](RansacOptions& o) { o.max_iterations = 0; }, "max_iterations");
  rejects([](RansacOptions& o) { o.min_iterations = 200; }, "min_iterations");
  rejects([](RansacOptions& o) { o.success_probability = 1; }, "success_probability");
  rejects([](RansacOptions& o) { o.prosac_horizon = 0.5; }, "prosac_horizon");
  rejects([](RansacOptions& o) { o.random_inlier_probability = 0; }, "random_inlier_probability");
  rejects([](RansacOptions& o) { o.non_randomness = 1; }, "non_randomness");
  rejects([](RansacOptions& o) { o.min_support = -1; }, "min_support");
  rejects([](RansacOptions& o) { o.max_shared_inliers = 1; }, "max_shared_inliers");
}

}  // namespace
}  // namespace lmb
