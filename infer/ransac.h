// LO-RANSAC with PROSAC sampling, templated on a duck-typed estimator (the second of the pose
// tiers: minimal solver (infer/p3p.h) -> ransac<Estimator> -> estimate_absolute_pose
// (infer/pose_estimator.h)). The loop knows nothing of cameras; the estimator holds the data, its
// units and its inlier threshold.
//
// The estimator contract (see AbsolutePoseEstimator in infer/pose_estimator.cc, and the mock
// estimators of test/infer/ransac_test.cc):
//
//   struct MyEstimator {
//     using Model = ...;                        // copyable
//     static constexpr int kSampleSize = 3;     // data per minimal sample, >= 1
//     int num_data() const;                     // N
//     // The minimal solver on data sample[0 .. kSampleSize): appends 0 or more models.
//     void generate_models(const int* sample, std::vector<Model>* models);
//     // MSAC cost of a model (lower is better: the sum over all data of min(residual, threshold)),
//     // and its inlier count (residual < threshold).
//     double score(const Model& model, int* num_inliers) const;
//     // Inlier flags of a model: (*mask)[i] = 1 when datum i is an inlier; resized to N.
//     void inliers(const Model& model, std::vector<char>* mask) const;
//     // Local optimisation: improves *model on its own inliers (e.g. non-linear least squares and
//     // re-selection of the inliers). The loop keeps the result only when its score is lower.
//     // final = false inside the loop (a few steps suffice to rank hypotheses), true once for the
//     // answer (to convergence).
//     void refine(Model* model, bool final) const;
//   };
//
// The loop (Chum, Matas, Kittler, "Locally optimized RANSAC", 2003; Chum, Matas, "Matching with
// PROSAC - progressive sample consensus", CVPR 2005):
// - Sampling. With options.progressive the data must be in decreasing order of quality (index 0
//   the most promising). Sample t (1-based) is drawn from the top n(t) data U_n: datum n(t) - 1
//   plus kSampleSize - 1 others drawn uniformly from U_{n(t)-1}, where n(t) grows by PROSAC's
//   growth function T'_n (T_N = options.prosac_horizon samples for U_N, by default
//   max_iterations); once n(t) = N, samples are uniform over all data. Without progressive, every sample is uniform
//   over all data.
// - Scoring. Every model of every sample is scored (MSAC). When the sample's best model has a
//   lower cost than every minimal model before it, it is refined (local optimisation,
//   refine(model, false)) and the refinement kept if its cost is lower; the best model so far
//   (refined or not) is the answer. A final refinement (refine(answer, true)) polishes the answer
//   and is kept if its cost is not higher.
// - Stopping (the PROSAC criteria; with uniform sampling they reduce to the standard RANSAC
//   bound). For each subset size n, I_n is the number of the best model's inliers among the top n
//   data. n is a stopping subset when I_n is non-random: I_n >= I_min(n) = kSampleSize +
//   ceil(mu + z sigma), the upper ends of a normal approximation of the support that a wrong
//   model gathers by chance among the n - kSampleSize other data (each an inlier with probability
//   options.random_inlier_probability = beta; mu = (n - m) beta, sigma^2 = (n - m) beta (1 - beta),
//   z the standard normal quantile of 1 - options.non_randomness), and I_n >= options.min_support.
//   The search stops once, for some stopping subset n, the samples drawn entirely inside U_n
//   reach k_n = log(1 - success_probability) / log(1 - P_n), P_n = prod_{j < m} (I_n - j) / (n - j)
//   the probability that a sample from U_n is all inliers (maximality: a better model would have
//   been found with probability success_probability). Also at options.max_iterations samples; never
//   before options.min_iterations.
// - Runner-up. Besides the answer the loop keeps up to kRunnerUpPool hypotheses that are
//   different from each other: two hypotheses belong to one family when more than
//   options.max_shared_inliers of the smaller inlier set are inliers of both, and a family keeps its
//   lowest cost. At the end the runner-up is the lowest-cost kept hypothesis whose shared inliers
//   with the answer are at most max_shared_inliers of its own inliers (a pose explaining mostly
//   other data, e.g. an aliased place); it is refined once like the answer. Its support tells how
//   ambiguous the answer is.
//
// Determinism: the result is a function of the estimator's data, the options and the seed; the
// loop keeps no global state and may run concurrently on separate estimators.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "common/random.h"
#include "infer/export.h"

namespace lmb {

struct LMB_INFER_EXPORT RansacOptions {
  // Most samples (minimal solver calls); a sample may give several models (P3P: up to 4).
  int max_iterations = 100;
  // Fewest samples before a stopping criterion may end the search.
  int min_iterations = 0;
  // Probability that no model with more inliers among a stopping subset was missed, in (0, 1).
  double success_probability = 0.9999;
  // PROSAC: the data are ordered by decreasing quality; false = uniform sampling.
  bool progressive = true;
  // PROSAC's T_N: the samples after which PROSAC samples from all N data (>= 1); 0 = max_iterations,
  // so that the last samples reach every datum.
  double prosac_horizon = 0.0;
  // Non-randomness: beta, the probability that a datum not in the sample is an inlier of a wrong
  // model by chance, in (0, 1); psi, the accepted probability that a random model's support
  // reaches I_min(n), in (0, 1); and the fewest inliers of a stopping subset (>= 0).
  double random_inlier_probability = 0.01;
  double non_randomness = 0.05;
  int min_support = 0;
  // Runner-up: hypotheses sharing more than this fraction of the smaller inlier set are one
  // family, in [0, 1).
  double max_shared_inliers = 0.5;
  uint64_t seed = 0;

  // Throws lmb::Error naming the field.
  void check() const;
};

struct LMB_INFER_EXPORT RansacStats {
  int num_data = 0;                                        // N
  int iterations = 0;                                      // samples drawn
  int models = 0;                                          // models scored (solver outputs, refinements excluded)
  int num_inliers = 0;                                     // of the answer
  double inlier_ratio = 0.0;                               // num_inliers / N
  double score = std::numeric_limits<double>::infinity();  // MSAC cost of the answer
  int refinements = 0;                                     // local optimisations run (answer and runner-up)
  int subset_size = 0;  // PROSAC's sampling subset n at the end (N with uniform sampling)
  int stop_subset = 0;  // the stopping subset n that ended the search; 0 = the iteration cap
  // The runner-up (see the file comment): 0 inliers when there is none.
  int runner_up_inliers = 0;
  int runner_up_shared = 0;  // of its inliers, those also inliers of the answer
  double runner_up_score = std::numeric_limits<double>::infinity();
};

// The loop's parts, public so that ransac<> can be instantiated by library users.

// PROSAC's sampler (see the file comment); uniform when progressive is false.
class LMB_INFER_EXPORT ProsacSampler {
 public:
  ProsacSampler(int num_data, int sample_size, bool progressive, double horizon, uint64_t seed);
  // Draws the next sample: sample_size distinct indices in [0, N), into sample[].
  void draw(int* sample);
  int64_t samples() const { return t_; }
  // The current subset size n(t) (N once sampling is uniform).
  int subset_size() const { return n_; }
  // Samples drawn so far whose indices all lie in [0, n).
  int64_t samples_within(int n) const { return n >= n_ ? t_ : left_at_[n]; }

 private:
  void draw_uniform(int count, int range, int* out);

  Rng rng_;
  int num_data_;
  int sample_size_;
  int n_;
  int64_t t_ = 0;
  std::vector<double> grow_at_;   // T'_n for n in [0, N]: n grows past n after sample T'_n
  std::vector<int64_t> left_at_;  // samples drawn before n(t) passed n
};

// The PROSAC stopping rule for one best model: the samples needed within each stopping subset.
class LMB_INFER_EXPORT ProsacStopping {
 public:
  ProsacStopping(int num_data, int sample_size, const RansacOptions& options);
  // Records the best model's inlier flags (in data order).
  void update(const std::vector<char>& inlier_mask);
  // The smallest stopping subset n whose samples_within(n) reached k_n, or 0.
  int satisfied(const ProsacSampler& sampler) const;
  int min_inliers(int n) const { return min_inliers_[n]; }

 private:
  int num_data_;
  int sample_size_;
  bool progressive_;
  double log_failure_;
  std::vector<int> min_inliers_;                    // I_min(n), n in [0, N]
  std::vector<std::pair<int, double>> candidates_;  // (n, k_n) of the stopping subsets
};

template <typename Estimator>
RansacStats ransac(Estimator& estimator, const RansacOptions& options, typename Estimator::Model* best_model,
                   typename Estimator::Model* runner_up_model = nullptr);

// ---- Implementation ------------------------------------------------------------------------

constexpr int kRunnerUpPool = 8;

namespace ransac_detail {

inline int shared_count(const std::vector<char>& a, const std::vector<char>& b) {
  int shared = 0;
  for (size_t i = 0; i < a.size(); ++i) shared += a[i] & b[i];
  return shared;
}

// Up to kRunnerUpPool scored hypotheses that share few inliers with each other, from which the
// runner-up (the best hypothesis explaining mostly other data than the winner) is drawn at the end.
template <typename Estimator>
class RunnerUpPool {
 public:
  using Model = typename Estimator::Model;

  RunnerUpPool(Estimator& estimator, const RansacOptions& options) : estimator_(estimator), options_(options) {
    pool_.reserve(kRunnerUpPool);
  }

  // Offers a scored hypothesis: it replaces a kept one it mostly agrees with when it scores
  // better, else the worst kept one when the pool is full and it scores better than that.
  void offer(const Model& model, double score, int inliers) {
    if (inliers <= Estimator::kSampleSize) return;
    int worst = -1;
    for (int k = 0; k < static_cast<int>(pool_.size()); ++k) {
      if (worst < 0 || pool_[k].score > pool_[worst].score) worst = k;
    }
    if (static_cast<int>(pool_.size()) == kRunnerUpPool && score >= pool_[worst].score) return;
    estimator_.inliers(model, &mask_);
    for (Kept& k : pool_) {
      const int shared = shared_count(mask_, k.mask);
      if (shared > options_.max_shared_inliers * std::min(inliers, k.inliers)) {
        if (score < k.score) k = Kept{model, score, inliers, mask_};
        return;
      }
    }
    if (static_cast<int>(pool_.size()) == kRunnerUpPool) {
      pool_[worst] = Kept{model, score, inliers, mask_};
    } else {
      pool_.push_back(Kept{model, score, inliers, mask_});
    }
  }

  // The lowest-cost kept hypothesis that mostly explains other data than best_mask, locally
  // refined when that lowers its cost without making it agree with the winner; fills the
  // runner-up fields of stats (and counts the refinement).
  void pick(const std::vector<char>& best_mask, RansacStats* stats, Model* runner_up_model) {
    std::sort(pool_.begin(), pool_.end(), [](const Kept& a, const Kept& b) { return a.score < b.score; });
    for (const Kept& k : pool_) {
      if (shared_count(k.mask, best_mask) > options_.max_shared_inliers * k.inliers) continue;
      Kept runner = k;
      Model refined = k.model;
      estimator_.refine(&refined, false);
      ++stats->refinements;
      int refined_inliers = 0;
      const double refined_score = estimator_.score(refined, &refined_inliers);
      if (refined_score < runner.score) {
        estimator_.inliers(refined, &mask_);
        if (shared_count(mask_, best_mask) <= options_.max_shared_inliers * refined_inliers) {
          runner = Kept{refined, refined_score, refined_inliers, mask_};
        }
      }
      stats->runner_up_inliers = runner.inliers;
      stats->runner_up_shared = shared_count(runner.mask, best_mask);
      stats->runner_up_score = runner.score;
      if (runner_up_model != nullptr) *runner_up_model = runner.model;
      return;
    }
  }

 private:
  struct Kept {
    Model model;
    double score;
    int inliers;
    std::vector<char> mask;
  };
  Estimator& estimator_;
  const RansacOptions& options_;
  std::vector<Kept> pool_;
  std::vector<char> mask_;
};

}  // namespace ransac_detail

template <typename Estimator>
RansacStats ransac(Estimator& estimator, const RansacOptions& options, typename Estimator::Model* best_model,
                   typename Estimator::Model* runner_up_model) {
  using Model = typename Estimator::Model;
  constexpr int m = Estimator::kSampleSize;
  static_assert(m >= 1, "kSampleSize must be >= 1");
  options.check();
  RansacStats stats;
  const int n = estimator.num_data();
  stats.num_data = n;
  stats.subset_size = n;
  if (n < m) return stats;

  const double horizon = options.prosac_horizon > 0 ? options.prosac_horizon : options.max_iterations;
  ProsacSampler sampler(n, m, options.progressive, horizon, options.seed);
  ProsacStopping stopping(n, m, options);
  ransac_detail::RunnerUpPool<Estimator> pool(estimator, options);

  double best_score = std::numeric_limits<double>::infinity();
  int best_inliers = 0;
  bool have_best = false;
  double best_minimal_score = std::numeric_limits<double>::infinity();
  std::vector<char> best_mask;
  auto accept = [&](const Model& model, double score, int inliers) {
    *best_model = model;
    best_score = score;
    best_inliers = inliers;
    have_best = true;
    estimator.inliers(model, &best_mask);
    stopping.update(best_mask);
  };

  std::vector<int> sample(m);
  std::vector<Model> models;
  while (sampler.samples() < options.max_iterations) {
    if (sampler.samples() >= options.min_iterations && have_best) {
      const int stop = stopping.satisfied(sampler);
      if (stop > 0) {
        stats.stop_subset = stop;
        break;
      }
    }
    sampler.draw(sample.data());
    models.clear();
    estimator.generate_models(sample.data(), &models);
    int candidate = -1;
    double candidate_score = 0.0;
    int candidate_inliers = 0;
    for (size_t k = 0; k < models.size(); ++k) {
      int inliers = 0;
      const double score = estimator.score(models[k], &inliers);
      ++stats.models;
      if (!std::isfinite(score)) continue;
      pool.offer(models[k], score, inliers);
      if (score < best_minimal_score) {
        if (candidate < 0 || score < candidate_score) {
          candidate = static_cast<int>(k);
          candidate_score = score;
          candidate_inliers = inliers;
        }
      }
    }
    if (candidate < 0) continue;
    best_minimal_score = std::min(best_minimal_score, candidate_score);
    if (candidate_score < best_score) accept(models[candidate], candidate_score, candidate_inliers);
    // Local optimisation of the sample's best model.
    Model refined = models[candidate];
    estimator.refine(&refined, false);
    ++stats.refinements;
    int refined_inliers = 0;
    const double refined_score = estimator.score(refined, &refined_inliers);
    if (refined_score < best_score) accept(refined, refined_score, refined_inliers);
  }
  stats.iterations = static_cast<int>(sampler.samples());
  stats.subset_size = sampler.subset_size();
  if (!have_best) return stats;

  {
    Model refined = *best_model;
    estimator.refine(&refined, true);
    ++stats.refinements;
    int refined_inliers = 0;
    const double refined_score = estimator.score(refined, &refined_inliers);
    if (refined_score <= best_score) accept(refined, refined_score, refined_inliers);
  }
  stats.num_inliers = best_inliers;
  stats.inlier_ratio = static_cast<double>(best_inliers) / n;
  stats.score = best_score;
  pool.pick(best_mask, &stats, runner_up_model);
  return stats;
}

}  // namespace lmb
