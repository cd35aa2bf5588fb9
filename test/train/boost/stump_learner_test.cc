#include "train/boost/stump_learner.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include <gtest/gtest.h>

#include "common/error.h"
#include "train/boost/synthetic_problem.h"

namespace lmb {
namespace {

using Entries = std::vector<SerialStumpLearner::Entry>;

struct ClassTotals {
  std::vector<double> w, y;
};
ClassTotals class_totals(const Entries& entries, int32_t C1) {
  ClassTotals t{std::vector<double>(C1, 0.0), std::vector<double>(C1, 0.0)};
  for (const auto& e : entries) {
    t.w[e.cls] += e.weight;
    t.y[e.cls] += e.z * e.weight;
  }
  return t;
}

// Squared error sum w (z - h)^2 of a stump (with fitted k_c for the classes outside S).
double stump_error(const Entries& entries, const FeatureMatrix& f, const SharedStump& s, const ClassTotals& t) {
  std::vector<uint8_t> in_s(t.w.size(), 0);
  for (int32_t c : s.classes) in_s[c] = 1;
  double j = 0.0;
  for (const auto& e : entries) {
    double h;
    if (in_s[e.cls]) {
      h = (f.column(s.dim)[e.sample] > s.theta ? s.a : 0.0) + s.b;
    } else {
      h = t.w[e.cls] > 0 ? t.y[e.cls] / t.w[e.cls] : 0.0;
    }
    j += e.weight * (e.z - h) * (e.z - h);
  }
  return j;
}

// Error of the constants-only fit: sum_c (W_c - Y_c^2 / W_c).
double constants_error(const ClassTotals& t) {
  double j = 0;
  for (size_t c = 0; c < t.w.size(); ++c) j += t.w[c] > 0 ? t.w[c] - t.y[c] * t.y[c] / t.w[c] : 0.0;
  return j;
}

struct PerClass {
  std::vector<double> wp, yp, wm, ym;
};
// Per-class sums above / below theta of one dim, in doubles, straight from the entries.
PerClass per_class(const Entries& entries, const FeatureMatrix& f, int32_t dim, int theta, int32_t C1) {
  PerClass p{std::vector<double>(C1, 0), std::vector<double>(C1, 0), std::vector<double>(C1, 0),
             std::vector<double>(C1, 0)};
  for (const auto& e : entries) {
    if (f.column(dim)[e.sample] > theta) {
      p.wp[e.cls] += e.weight;
      p.yp[e.cls] += e.z * e.weight;
    } else {
      p.wm[e.cls] += e.weight;
      p.ym[e.cls] += e.z * e.weight;
    }
  }
  return p;
}

double set_gain(double wp, double yp, double wm, double ym, double q) {
  return (wp > 0 ? yp * yp / wp : 0.0) + (wm > 0 ? ym * ym / wm : 0.0) - q;
}

std::vector<int> distinct_thresholds(const FeatureMatrix& f, int32_t dim) {
  std::set<int> values(f.column(dim), f.column(dim) + f.num_samples);
  std::vector<int> t(values.begin(), values.end());
  if (!t.empty()) t.pop_back();
  return t;
}

// The best gain over `dims`, all thresholds and all 2^C1 - 1 sharing sets.
double exhaustive_best_gain(const Entries& entries, const FeatureMatrix& f, const std::vector<int32_t>& dims,
                            int32_t C1) {
  const ClassTotals t = class_totals(entries, C1);
  std::vector<double> q(C1);
  for (int32_t c = 0; c < C1; ++c) q[c] = t.w[c] > 0 ? t.y[c] * t.y[c] / t.w[c] : 0.0;
  double best = 0.0;
  for (int32_t d : dims) {
    for (int theta : distinct_thresholds(f, d)) {
      const PerClass p = per_class(entries, f, d, theta, C1);
      for (uint32_t mask = 1; mask < (1u << C1); ++mask) {
        double wp = 0, yp = 0, wm = 0, ym = 0, qs = 0;
        for (int32_t c = 0; c < C1; ++c) {
          if (mask & (1u << c)) {
            wp += p.wp[c];
            yp += p.yp[c];
            wm += p.wm[c];
            ym += p.ym[c];
            qs += q[c];
          }
        }
        best = std::max(best, set_gain(wp, yp, wm, ym, qs));
      }
    }
  }
  return best;
}

// Torralba's greedy forward selection (add the class that helps most, keep the best prefix).
double greedy_best_gain(const Entries& entries, const FeatureMatrix& f, const std::vector<int32_t>& dims,
                        const std::vector<std::vector<int>>& thresholds, int32_t C1) {
  const ClassTotals t = class_totals(entries, C1);
  std::vector<double> q(C1);
  for (int32_t c = 0; c < C1; ++c) q[c] = t.w[c] > 0 ? t.y[c] * t.y[c] / t.w[c] : 0.0;
  double best = 0.0;
  for (size_t i = 0; i < dims.size(); ++i) {
    for (int theta : thresholds[i]) {
      const PerClass p = per_class(entries, f, dims[i], theta, C1);
      std::vector<uint8_t> in(C1, 0);
      double wp = 0, yp = 0, wm = 0, ym = 0, qs = 0;
      for (int32_t step = 0; step < C1; ++step) {
        int32_t pick = -1;
        double pick_gain = -INFINITY;
        for (int32_t c = 0; c < C1; ++c) {
          if (in[c]) continue;
          const double g = set_gain(wp + p.wp[c], yp + p.yp[c], wm + p.wm[c], ym + p.ym[c], qs + q[c]);
          if (g > pick_gain) {
            pick_gain = g;
            pick = c;
          }
        }
        in[pick] = 1;
        wp += p.wp[pick];
        yp += p.yp[pick];
        wm += p.wm[pick];
        ym += p.ym[pick];
        qs += q[pick];
        best = std::max(best, pick_gain);
      }
    }
  }
  return best;
}

SyntheticBoostOptions tiny_options(int classes) {
  SyntheticBoostOptions o;
  o.num_classes = classes;
  o.observations_per_class = 6;
  o.validation_per_class = 1;
  o.num_background = 20;
  o.context_dims = 8;
  o.descriptor_bits = 4;
  o.signature_dims = 2;
  o.noise_density = 0.3;
  o.seed = 11;
  return o;
}

TEST(StumpLearner, ChosenStumpEqualsExhaustiveSearch) {
  for (int classes : {3, 6, 9}) {
    const SyntheticBoostProblem p = make_synthetic_boost_problem(tiny_options(classes));
    const int32_t C1 = p.set.num_classes_with_background();
    BoostOptions o;
    o.num_rounds = 12;
    o.dims_per_round = p.features.num_dims;
    o.screening.max_thresholds = 0;  // all thresholds
    o.screening.refine_top = 0;      // full search everywhere
    o.negatives.per_class = 8;
    o.mining.interval = 4;
    o.learning_rate = 1.0;  // the model then stores the fitted a, b themselves (shrinkage scales them)
    SerialStumpLearner learner(p.features, p.set, o);
    learner.initialize();
    std::vector<int32_t> all_dims(static_cast<size_t>(p.features.num_dims));
    for (int32_t d = 0; d < p.features.num_dims; ++d) all_dims[d] = d;
    double worst = 0.0;
    for (int r = 0; r < o.num_rounds; ++r) {
      if (r > 0 && r % o.mining.interval == 0) {
        // Mining changes the entries at the start of the round: run it, compare from the next.
        learner.run_round();
        continue;
      }
      const Entries before = learner.entries();
      learner.run_round();
      const SharedStump& s = learner.model().stumps.back();
      const ClassTotals t = class_totals(before, C1);
      const double j0 = constants_error(t);
      const double j = stump_error(before, p.features, s, t);
      const double best = exhaustive_best_gain(before, p.features, all_dims, C1);
      const double j_best = j0 - best;
      ASSERT_GT(j_best, 0.0);
      const double rel = (j - j_best) / j_best;
      worst = std::max(worst, rel);
      EXPECT_LE(rel, 1e-9) << classes << " classes, round " << r;
    }
    std::printf("exhaustive check, %d classes + background: worst relative excess cost %.3g\n", classes, worst);
  }
}

TEST(StumpLearner, FastSharingReachesGreedyCostReduction) {
  SyntheticBoostOptions so;
  so.num_classes = 63;  // + background = 64 classes
  so.observations_per_class = 8;
  so.context_dims = 48;
  so.descriptor_bits = 16;
  so.num_background = 150;
  const SyntheticBoostProblem p = make_synthetic_boost_problem(so);
  const int32_t C1 = p.set.num_classes_with_background();
  for (const auto& [refine_top, max_thresholds] : std::vector<std::pair<int, int>>{{32, 8}, {0, 8}, {32, 4}}) {
    BoostOptions o;
    o.num_rounds = 20;
    o.dims_per_round = 16;
    o.screening.refine_top = refine_top;
    o.screening.max_thresholds = max_thresholds;
    o.mining.interval = 0;
    o.learning_rate = 1.0;  // the cost reduction is measured with the stored (unshrunk) stump
    SerialStumpLearner learner(p.features, p.set, o);
    learner.initialize();
    double ratio_sum = 0.0;
    double fast_total = 0.0, greedy_total = 0.0;
    for (int r = 0; r < o.num_rounds; ++r) {
      const Entries before = learner.entries();
      const std::vector<int32_t> dims = draw_round_dims(o.seed, r, p.features.num_dims, o.dims_per_round);
      // The greedy reference gets every threshold (the learner at most max_thresholds_per_dim).
      std::vector<std::vector<int>> thresholds;
      for (int32_t d : dims) {
        thresholds.push_back(distinct_thresholds(p.features, d));
      }
      learner.run_round();
      const SharedStump& s = learner.model().stumps.back();
      const ClassTotals t = class_totals(before, C1);
      const double fast = constants_error(t) - stump_error(before, p.features, s, t);
      // Greedy over all thresholds of the same dims: an upper reference for the reduced set.
      const double greedy = greedy_best_gain(before, p.features, dims, thresholds, C1);
      ASSERT_GT(greedy, 0.0);
      ratio_sum += fast / greedy;
      fast_total += fast;
      greedy_total += greedy;
    }
    const double mean_ratio = ratio_sum / o.num_rounds;
    std::printf(
        "64 classes, refine_top %d (%d thresholds/dim max): fast / greedy cost reduction = %.4f "
        "(mean of per-round ratios), %.4f (totals)\n",
        refine_top, o.screening.max_thresholds, mean_ratio, fast_total / greedy_total);
    // The learner's default (8 candidate thresholds) must reach 99% of the greedy search over
    // every threshold; with 4 thresholds the threshold set, not the sharing search, costs ~4%.
    if (max_thresholds >= 8) {
      EXPECT_GE(mean_ratio, 0.99);
    }
  }
}

struct LearnedRun {
  std::vector<RoundStats> rounds;
  std::string model_bytes;
};

LearnedRun train_synthetic(const SyntheticBoostProblem& p, BoostOptions o) {
  SerialStumpLearner learner(p.features, p.set, o);
  LearnedRun run;
  learner.train([&](const RoundStats& s) { run.rounds.push_back(s); });
  run.model_bytes = serialize_boost_model(learner.model());
  return run;
}

// Precision@1 of exact Hamming nearest neighbour (descriptor bits only) over the training samples.
double hamming_nn_precision(const SyntheticBoostProblem& p) {
  const int64_t S = p.set.num_samples();
  std::vector<std::vector<uint8_t>> bits(static_cast<size_t>(S));
  for (int64_t s = 0; s < S; ++s) {
    for (int32_t b = 0; b < p.descriptor_bits; ++b) bits[s].push_back(p.features.column(p.context_dims + b)[s]);
  }
  int64_t correct = 0, total = 0;
  for (int64_t v = 0; v < S; ++v) {
    if (!p.set.sample_is_validation[v]) continue;
    int best = 1 << 30;
    int32_t best_class = -1;
    for (int64_t s = 0; s < S; ++s) {
      if (p.set.sample_is_validation[s]) continue;
      int d = 0;
      for (int32_t b = 0; b < p.descriptor_bits; ++b) d += bits[v][b] != bits[s][b];
      if (d < best) {
        best = d;
        best_class = p.set.sample_class[s];
      }
    }
    correct += best_class == p.set.sample_class[v];
    ++total;
  }
  return static_cast<double>(correct) / static_cast<double>(total);
}

TEST(StumpLearner, LearnsContextSeparableClassesAndCostDecreases) {
  const SyntheticBoostProblem p = make_synthetic_boost_problem(SyntheticBoostOptions());
  BoostOptions o;
  o.num_rounds = 250;
  o.dims_per_round = 100;
  o.mining.interval = 25;
  const LearnedRun run = train_synthetic(p, o);
  ASSERT_EQ(run.rounds.size(), 250u);
  int64_t mined = 0;
  for (size_t r = 0; r < run.rounds.size(); ++r) {
    const RoundStats& s = run.rounds[r];
    EXPECT_LT(s.cost, s.cost_before) << "round " << r;
    EXPECT_LE(s.squared_error, s.cost_before * (1 + 1e-12)) << "round " << r;
    if (r > 0 && s.mined == 0) {
      EXPECT_NEAR(s.cost_before, run.rounds[r - 1].cost, 1e-9 * s.cost_before);
    }
    mined += s.mined;
    EXPECT_GT(s.sharing_size, 0);
  }
  EXPECT_GT(mined, 0);
  const double boost_p1 = run.rounds.back().validation_p1;
  const double hamming_p1 = hamming_nn_precision(p);
  std::printf(
      "synthetic (40 classes in alias groups of 4): validation P@1 boost %.3f (round 1: %.3f) vs "
      "Hamming NN %.3f\n",
      boost_p1, run.rounds.front().validation_p1, hamming_p1);
  EXPECT_GT(boost_p1, hamming_p1 + 0.3);
  EXPECT_GE(run.rounds.back().validation_p1_landmarks, boost_p1);  // rejection can only cost
  EXPECT_GT(boost_p1, 0.7);

  // The serialized model scores the validation samples like the learner's incremental scores.
  const BoostModel model = deserialize_boost_model(run.model_bytes);
  std::vector<uint8_t> v(static_cast<size_t>(p.features.num_dims));
  int64_t correct = 0, total = 0;
  for (int64_t s = 0; s < p.set.num_samples(); ++s) {
    if (!p.set.sample_is_validation[s]) continue;
    for (int32_t d = 0; d < p.features.num_dims; ++d) v[d] = p.features.column(d)[s];
    correct += model.classify(v.data()) == p.set.sample_class[s];
    ++total;
  }
  EXPECT_NEAR(static_cast<double>(correct) / total, boost_p1, 1.5 / total);
}

TEST(StumpLearner, DeterministicBytes) {
  const SyntheticBoostProblem p = make_synthetic_boost_problem(SyntheticBoostOptions());
  BoostOptions o;
  o.num_rounds = 30;
  o.dims_per_round = 60;
  o.mining.interval = 10;
  const LearnedRun a = train_synthetic(p, o);
  const LearnedRun b = train_synthetic(p, o);
  EXPECT_EQ(a.model_bytes, b.model_bytes);
  o.seed = 2;
  const LearnedRun c = train_synthetic(p, o);
  EXPECT_NE(a.model_bytes, c.model_bytes);
}

TEST(StumpLearner, BlockedScreeningEqualsColumnPasses) {
  // The class-major blocked pass must give the column passes' screening gains bit for bit, so the
  // same candidates are refined and the models are byte-identical: dense and sparse dims, up to
  // 15 thresholds (and 20, where dims with more than 15 take column passes in the same round),
  // |F_m| not a multiple of the block of 8, mining on.
  SyntheticBoostOptions so;
  so.noise_density = 0.4;
  const SyntheticBoostProblem p = make_synthetic_boost_problem(so);
  for (const int32_t thresholds : {3, 8, 15, 20}) {
    BoostOptions o;
    o.num_rounds = 25;
    o.dims_per_round = 61;
    o.mining.interval = 10;
    o.screening.max_thresholds = thresholds;
    // The screening gains of every (dim, theta), after a few rounds (unequal weights).
    {
      BoostOptions first = o;
      first.num_rounds = 12;
      SerialStumpLearner blocked_learner(p.features, p.set, first);
      first.screening.blocked = false;
      SerialStumpLearner column_learner(p.features, p.set, first);
      for (int r = 0; r < 11; ++r) {
        blocked_learner.run_round();
        column_learner.run_round();
      }
      const std::vector<int32_t> dims = draw_round_dims(3, 0, p.features.num_dims, 61);
      const std::vector<ScreenedCandidate> b = blocked_learner.screen(dims), c = column_learner.screen(dims);
      ASSERT_EQ(b.size(), c.size()) << thresholds << " thresholds";
      ASSERT_GT(b.size(), 61u);
      for (size_t i = 0; i < b.size(); ++i) {
        EXPECT_EQ(b[i].dim, c[i].dim);
        EXPECT_EQ(b[i].theta, c[i].theta);
        EXPECT_EQ(b[i].gain, c[i].gain) << "dim " << b[i].dim << " theta " << b[i].theta;
      }
    }
    const LearnedRun blocked = train_synthetic(p, o);
    o.screening.blocked = false;
    const LearnedRun columns = train_synthetic(p, o);
    EXPECT_EQ(blocked.model_bytes, columns.model_bytes) << thresholds << " thresholds";
    ASSERT_EQ(blocked.rounds.size(), columns.rounds.size());
    for (size_t r = 0; r < blocked.rounds.size(); ++r) {
      EXPECT_EQ(blocked.rounds[r].gain, columns.rounds[r].gain) << "round " << r;
      EXPECT_EQ(blocked.rounds[r].dim, columns.rounds[r].dim) << "round " << r;
    }
  }
  // And the stumps differ from another draw of F_m: the comparison is not vacuous.
  BoostOptions o;
  o.num_rounds = 25;
  o.dims_per_round = 61;
  const LearnedRun a = train_synthetic(p, o);
  o.seed = 5;
  EXPECT_NE(a.model_bytes, train_synthetic(p, o).model_bytes);
}

TEST(StumpLearner, TrackedScoresEqualTheModelsScores) {
  const SyntheticBoostProblem p = make_synthetic_boost_problem(SyntheticBoostOptions());
  BoostOptions o;
  o.num_rounds = 37;
  o.dims_per_round = 50;
  o.negatives.per_class = 10;
  o.mining.interval = 10;
  o.mining.pool_size = 150;
  SerialStumpLearner learner(p.features, p.set, o);
  const int32_t C1 = p.set.num_classes_with_background();
  std::vector<uint8_t> v(static_cast<size_t>(p.features.num_dims));
  std::vector<double> scores(static_cast<size_t>(C1));
  for (int32_t rounds : {10, 24, 37}) {
    while (learner.rounds_done() < rounds) learner.run_round();
    const LearnerState st = learner.save_state();
    ASSERT_GT(st.tracked_samples.size(), static_cast<size_t>(st.num_validation_rows)) << "no mining pool";
    // Validation P@1 against a plain first-maximum over the state's scores.
    int64_t hits = 0, hits_landmarks = 0;
    const int32_t C = C1 - 1;
    for (int64_t r = 0; r < st.num_validation_rows; ++r) {
      const float* row = st.tracked_scores.data() + r * C1;
      int32_t best = 0;
      for (int32_t c = 1; c < C; ++c) {
        if (st.class_offset[c] + row[c] > st.class_offset[best] + row[best]) best = c;
      }
      const bool right = best == p.set.sample_class[st.tracked_samples[r]];
      hits_landmarks += right;
      hits += right && !(st.class_offset[C] + row[C] > st.class_offset[best] + row[best]);
    }
    ASSERT_GT(st.num_validation_rows, 0);
    EXPECT_EQ(learner.validation_precision(), static_cast<double>(hits) / st.num_validation_rows);
    EXPECT_EQ(learner.validation_precision(true), static_cast<double>(hits_landmarks) / st.num_validation_rows);
    for (size_t r = 0; r < st.tracked_samples.size(); ++r) {
      const int64_t s = st.tracked_samples[r];
      for (int32_t d = 0; d < p.features.num_dims; ++d) v[d] = p.features.column(d)[s];
      learner.model().scores(v.data(), scores.data());
      for (int32_t c = 0; c < C1; ++c) {
        const double tracked = st.class_offset[c] + st.tracked_scores[r * C1 + c];
        ASSERT_NEAR(tracked, scores[c], 1e-4 * (1.0 + std::abs(scores[c])))
            << "row " << r << " class " << c << " after " << rounds << " rounds";
      }
    }
  }
}

TEST(StumpLearner, LearningRateScalesTheFirstRoundExactly) {
  // Before the first update every weight is the same whatever the learning rate, so the first
  // stump (dim, theta, sharing set) is the same and a, b and the biases scale by nu exactly.
  const SyntheticBoostProblem p = make_synthetic_boost_problem(SyntheticBoostOptions());
  BoostOptions o;
  o.num_rounds = 1;
  o.dims_per_round = 60;
  o.learning_rate = 1.0;
  BoostOptions half = o;
  half.learning_rate = 0.5;
  SerialStumpLearner full_learner(p.features, p.set, o), half_learner(p.features, p.set, half);
  full_learner.train();
  half_learner.train();
  const BoostModel& m1 = full_learner.model();
  const BoostModel& m2 = half_learner.model();
  ASSERT_EQ(m1.stumps.size(), 1u);
  ASSERT_EQ(m2.stumps.size(), 1u);
  EXPECT_EQ(m1.stumps[0].dim, m2.stumps[0].dim);
  EXPECT_EQ(m1.stumps[0].theta, m2.stumps[0].theta);
  EXPECT_EQ(m1.stumps[0].classes, m2.stumps[0].classes);
  EXPECT_NE(m1.stumps[0].a, 0.0);
  EXPECT_DOUBLE_EQ(m2.stumps[0].a, 0.5 * m1.stumps[0].a);
  EXPECT_DOUBLE_EQ(m2.stumps[0].b, 0.5 * m1.stumps[0].b);
  for (size_t c = 0; c < m1.bias.size(); ++c) EXPECT_DOUBLE_EQ(m2.bias[c], 0.5 * m1.bias[c]) << c;
  BoostOptions bad = o;
  bad.learning_rate = 0.0;
  EXPECT_THROW(bad.check(), Error);
  bad.learning_rate = 1.5;
  EXPECT_THROW(bad.check(), Error);
}

TEST(StumpLearner, ClassBalanceKeepsAManyPositiveBackgroundFromWinningEverything) {
  // Ten times more background samples than landmark samples. With unit weights and a few
  // negatives, the background's constant drifts towards log(|L+| / |L-|) and it outscores the
  // right landmark on many held-out samples; balanced weights and every landmark sample as a
  // background negative (the defaults) keep precision@1 with rejection near the landmarks-only one.
  SyntheticBoostOptions so;
  so.num_background = 4000;
  const SyntheticBoostProblem p = make_synthetic_boost_problem(so);
  BoostOptions o;
  o.num_rounds = 120;
  o.dims_per_round = 100;
  o.learning_rate = 1.0;  // converges within the test's 120 rounds
  o.negatives.per_class = 40;
  BoostOptions unit = o;
  unit.negatives.weight_ratio = 0.0;
  unit.negatives.background = o.negatives.per_class;
  SerialStumpLearner balanced(p.features, p.set, o), unbalanced(p.features, p.set, unit);
  balanced.train();
  unbalanced.train();
  const double b = balanced.validation_precision(), b_lm = balanced.validation_precision(true);
  const double u = unbalanced.validation_precision(), u_lm = unbalanced.validation_precision(true);
  std::printf("background x10: P@1 with rejection / landmarks only: balanced %.3f / %.3f, unit weights %.3f / %.3f\n",
              b, b_lm, u, u_lm);
  EXPECT_LT(b_lm - b, 0.06);
  EXPECT_GT(u_lm - u, 0.15);
  EXPECT_GT(b, u + 0.08);
}

TEST(StumpLearner, RoundDimsAreACounterBasedDraw) {
  const auto a = draw_round_dims(5, 3, 1000, 50);
  EXPECT_EQ(a.size(), 50u);
  EXPECT_TRUE(std::is_sorted(a.begin(), a.end()));
  EXPECT_EQ(std::set<int32_t>(a.begin(), a.end()).size(), 50u);
  EXPECT_EQ(draw_round_dims(5, 3, 1000, 50), a);
  EXPECT_NE(draw_round_dims(5, 4, 1000, 50), a);
  EXPECT_NE(draw_round_dims(6, 3, 1000, 50), a);
}

TEST(StumpLearner, RejectsBadInput) {
  const SyntheticBoostProblem p = make_synthetic_boost_problem(SyntheticBoostOptions());
  BoostOptions o;
  o.num_rounds = 5;
  o.dims_per_round = 10;
  {  // zero rounds
    BoostOptions z = o;
    z.num_rounds = 0;
    EXPECT_THROW(SerialStumpLearner(p.features, p.set, z), Error);
  }
  {  // |F_m| larger than the dimension
    BoostOptions z = o;
    z.dims_per_round = p.features.num_dims + 1;
    EXPECT_THROW(SerialStumpLearner(p.features, p.set, z), Error);
  }
  {  // a class with no positives
    TrainingSet set = p.set;
    for (int64_t s = 0; s < set.num_samples(); ++s) {
      if (set.sample_class[s] == 3) set.sample_is_validation[s] = 1;
    }
    try {
      SerialStumpLearner l(p.features, set, o);
      FAIL() << "no error";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("no training positives"), std::string::npos);
    }
  }
  {  // NaN weight
    TrainingSet set = p.set;
    set.sample_weight.assign(static_cast<size_t>(set.num_samples()), 1.f);
    set.sample_weight[7] = std::nanf("");
    EXPECT_THROW(SerialStumpLearner(p.features, set, o), Error);
  }
  {  // all-identical features
    FeatureMatrix f = p.features;
    std::fill(f.data.begin(), f.data.end(), 3);
    try {
      SerialStumpLearner l(f, p.set, o);
      FAIL() << "no error";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("constant"), std::string::npos);
    }
  }
  {  // rows do not match the samples
    FeatureMatrix f = p.features;
    f.num_samples -= 1;
    f.data.resize(static_cast<size_t>(f.num_samples) * f.num_dims);
    EXPECT_THROW(SerialStumpLearner(f, p.set, o), Error);
  }
}

TEST(StumpLearner, MostlyConstantFeaturesGiveConstantStumpsNotNaN) {
  // Only one usable dim: rounds that do not draw it add a constants-only stump (dim -1).
  const SyntheticBoostProblem p = make_synthetic_boost_problem(SyntheticBoostOptions());
  FeatureMatrix f = p.features;
  for (int32_t d = 1; d < f.num_dims; ++d) std::fill(f.column(d), f.column(d) + f.num_samples, 0);
  BoostOptions o;
  o.num_rounds = 20;
  o.dims_per_round = 5;
  SerialStumpLearner learner(f, p.set, o);
  int constant = 0;
  learner.train([&](const RoundStats& s) {
    EXPECT_TRUE(std::isfinite(s.cost));
    EXPECT_LE(s.cost, s.cost_before * (1 + 1e-12));  // converged constants: equal up to rounding
    constant += s.dim < 0;
  });
  EXPECT_GT(constant, 0);
  EXPECT_NO_THROW(learner.model().check());
}

// candidate_dims restricts F_m to the leading (context) dims: a context-only classifier never
// reads a descriptor bit, while the same problem without the restriction does.
TEST(StumpLearner, CandidateDimsKeepsStumpsOnTheContextDims) {
  const SyntheticBoostProblem p = make_synthetic_boost_problem(SyntheticBoostOptions());
  BoostOptions o;
  o.num_rounds = 30;
  o.dims_per_round = 100;
  o.mining.interval = 0;
  o.validation.interval = 0;
  const auto stump_dims = [&](const BoostOptions& options) {
    SerialStumpLearner learner(p.features, p.set, options);
    learner.train([](const RoundStats&) {});
    std::vector<int32_t> dims;
    for (const SharedStump& s : learner.model().stumps) dims.push_back(s.dim);
    return dims;
  };
  const std::vector<int32_t> all = stump_dims(o);
  EXPECT_TRUE(std::any_of(all.begin(), all.end(), [&](int32_t d) { return d >= p.context_dims; }));
  o.candidate_dims = p.context_dims;
  const std::vector<int32_t> context = stump_dims(o);
  ASSERT_EQ(context.size(), 30u);
  for (int32_t d : context) EXPECT_LT(d, p.context_dims);
  o.candidate_dims = p.features.num_dims + 1;
  EXPECT_THROW(SerialStumpLearner(p.features, p.set, o), Error);
}

}  // namespace
}  // namespace lmb
