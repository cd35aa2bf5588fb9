// The serial JointBoost (GentleBoost with shared stumps) learner for thousands of classes.
//
// A round: mine hard negatives when due (NegativeMiner), quantize the entries' weights to this
// round's fixed point (EntryStore), draw F_m (counter-based on (seed, round)), choose this rank's
// dims (hook), screen them and run the full sharing-set search on the best candidates
// (StumpSearch over ColumnScreener and FeatureColumns), agree on the best stump (hook), then fit
// it and the per-class constants k_c, update every entry's weight w <- w exp(-z h), the tracked
// validation and mining-pool scores (TrackedRows) and the model.
//
// Every sum the search compares is an integer sum (train/boost/entry_store.h): the result does not
// depend on summation order, so a distributed layer (train/dist/feature_parallel_learner.h) that
// splits dims across ranks reproduces this learner's model bit for bit. The learner exchanges
// what it must through a Collectives (train/boost/collectives.h): the tracked rows are split over
// its ranks; the rest is replicated.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "train/boost/boost_model.h"
#include "train/boost/boost_options.h"
#include "train/boost/collectives.h"
#include "train/boost/entry_store.h"
#include "train/boost/feature_columns.h"
#include "train/boost/learner_state.h"
#include "train/boost/negative_miner.h"
#include "train/boost/stump_record.h"
#include "train/boost/stump_search.h"
#include "train/boost/tracked_rows.h"
#include "train/boost/training_set.h"
#include "train/features/feature_matrix.h"

namespace lmb {

struct RoundStats {
  int32_t round = 0;           // 0-based
  double cost_before = 0.0;    // exponential loss sum w before the update (after mining)
  double cost = 0.0;           // exponential loss sum w after the update
  double squared_error = 0.0;  // the paper's J of the fitted stump (weighted squared error)
  double gain = 0.0;           // squared-error reduction of sharing vs. constants only
  int32_t dim = -1;
  int32_t theta = 0;
  int32_t sharing_size = 0;
  double validation_p1 = -1.0;            // precision@1 on held-out samples; -1 = not evaluated
  double validation_p1_landmarks = -1.0;  // the same with the background class left out (no rejection)
  int64_t num_entries = 0;
  int64_t mined = 0;               // negatives added by mining at the start of this round
  double seconds = 0.0;            // whole round
  double seconds_histogram = 0.0;  // screening passes over the columns (sums and screening gains)
  double seconds_search = 0.0;     // candidate selection and the sharing-set searches
  double seconds_update = 0.0;     // weights, scores, model
  double seconds_eval = 0.0;       // validation and mining
};

// Sums of rounds' statistics (the benchmarks' time split).
struct RoundTotals {
  int32_t rounds = 0;
  double seconds = 0.0, histogram = 0.0, search = 0.0, update = 0.0, eval = 0.0, sharing_size = 0.0;
  void add(const RoundStats& s) {
    ++rounds;
    seconds += s.seconds;
    histogram += s.seconds_histogram;
    search += s.seconds_search;
    update += s.seconds_update;
    eval += s.seconds_eval;
    sharing_size += s.sharing_size;
  }
};

// F_m of a round: the k dims with the smallest counter_hash(seed, tag, round, dim), ascending.
// Independent of rank count and resume.
std::vector<int32_t> draw_round_dims(uint64_t seed, int32_t round, int32_t num_dims, int32_t k);

class SerialStumpLearner {
 public:
  // `features` rows are the samples of `set` (features.num_samples == set.num_samples()); features,
  // set and comm must outlive the learner. Throws lmb::Error on bad options
  // (options.check(num_dims)), a bad set (set.check()), size mismatch, or features whose stored
  // columns are all constant.
  SerialStumpLearner(const FeatureMatrix& features, const TrainingSet& set, const BoostOptions& options,
                     Collectives& comm = one_process());
  virtual ~SerialStumpLearner() = default;
  SerialStumpLearner(const SerialStumpLearner&) = delete;
  SerialStumpLearner& operator=(const SerialStumpLearner&) = delete;

  // Bootstraps the negatives and sets every weight to its initial value. Called by the first
  // round if not before.
  void initialize();
  // One boosting round. Throws lmb::Error if the weights stop being finite.
  RoundStats run_round();
  // Runs the remaining rounds; on_round sees each round's statistics.
  void train(const std::function<void(const RoundStats&)>& on_round = {});

  const BoostModel& model() const { return model_; }
  int32_t rounds_done() const { return static_cast<int32_t>(model_.stumps.size()); }
  const BoostOptions& options() const { return options_; }

  // The current entries with true weights (tests, checkpoints), sample-major order.
  using Entry = EntryStore::Entry;
  std::vector<Entry> entries() const { return entries_.entries(); }
  double exp_loss() const { return entries_.exp_loss(); }  // sum of true weights
  // Precision@1 of the tracked validation samples under the current model, -1 without any.
  // exclude_background: best landmark class only (the top-1 ranking without rejection).
  // Collective (every rank holds some rows): call it on every rank.
  double validation_precision(bool exclude_background = false);

  // The search of one round without changing state (tests): best record over `dims` (global dims,
  // all stored here) with the current weights.
  StumpRecord search(const std::vector<int32_t>& dims);
  // The screening of those dims alone (tests): every (dim, theta) with a positive screening gain,
  // by ascending dim.
  std::vector<ScreenedCandidate> screen(std::vector<int32_t> dims);

  // Everything that changes during training (train/boost/learner_state.h). Initializes the
  // learner first if no round ran yet. Collective: the tracked scores are gathered to rank 0,
  // whose state is complete; the other ranks' states leave tracked_scores empty.
  LearnerState save_state();
  // Continues from a saved state, bit for bit, on any rank count. Throws lmb::Error when the state
  // does not fit this learner's set and options (sizes, classes, samples, dims out of range, more
  // rounds than options().num_rounds); the learner is then unchanged.
  void restore_state(const LearnerState& state);

 protected:
  // Hooks for a distributed layer.
  // This rank's share of the round's dims (default: all of them; each must be stored here).
  virtual std::vector<int32_t> choose_dims(int32_t round, const std::vector<int32_t>& round_dims);
  // Picks the candidates for the full search from this rank's screened ones (default: the
  // refine_top best by (gain, dim, theta)). A distributed layer gathers and picks globally.
  virtual std::vector<ScreenedCandidate> select_for_refinement(std::vector<ScreenedCandidate> local);
  // The round's stump from every rank's best (default: this one) and its split of the samples:
  // above[s] = [v_dim(s) > theta] for every sample (all 0 when no stump gains).
  virtual StumpRecord reduce_best(StumpRecord local, std::vector<uint8_t>* above);

  FeatureColumns& columns() { return columns_; }

  const FeatureMatrix& features_;
  const TrainingSet& set_;
  const BoostOptions options_;
  Collectives& comm_;

 private:
  // Fits the round's stump and constants and applies them: weights, tracked rows, model.
  void apply(const StumpRecord& best, const std::vector<uint8_t>& above, RoundStats* stats);

  int32_t C1_ = 0;  // classes including background
  FeatureColumns columns_;
  EntryStore entries_;
  StumpSearch search_;
  TrackedRows rows_;
  NegativeMiner miner_;
  BoostModel model_;
  bool initialized_ = false;
  double last_validation_ = -1.0;
};

}  // namespace lmb
