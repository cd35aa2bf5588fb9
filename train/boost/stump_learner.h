// The serial JointBoost (GentleBoost with shared stumps) learner for thousands of classes.
//
// State: per-class entry lists (the paper's L+_c and L-_c) stored sample-major: entry e is
// (sample, class, z = +1 / -1, weight). Weights are doubles (true weight = stored * 2^exponent);
// each round they are quantised to int64 fixed point (a power-of-two scale chosen from the global
// maximum and entry count so that any sum of entries fits), and every histogram and set sum is an
// integer sum: the result does not depend on summation order, so a distributed layer that splits
// dims or samples across ranks and sums integers reproduces the serial model bit for bit.
//
// A round: draw F_m (counter-based on (seed, round)), choose this rank's dims (hook), screen them:
// eight dims at a time, one class-major pass over the entries reads each sample's 4-bit buckets of
// the eight dims and builds per-(class, bucket) sums of w for positives and negatives, from which
// a cheap screening search ranks every (dim, theta) (dims with more than 15 thresholds get a
// sample-major column pass each); the best `refine_top` candidates get the full sharing-set
// search (train/boost/sharing_set.h), the best record is reduced (hook), then w <- w exp(-z h) on
// every entry, incremental scores of validation and mining-pool samples are updated, and every
// mining_interval rounds hard negatives are added.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <utility>
#include <vector>

#include "train/boost/boost_model.h"
#include "train/boost/boost_options.h"
#include "train/boost/learner_state.h"
#include "train/boost/sharing_set.h"
#include "train/boost/training_set.h"
#include "train/features/feature_matrix.h"

namespace lmb {

// The small record a reduction carries: the best stump of a rank.
struct StumpRecord {
  double gain = -std::numeric_limits<double>::infinity();  // G(S) in weight units; higher is better
  int32_t dim = -1;                // global dim, -1 = none
  int32_t theta = 0;               // threshold bin
  std::vector<int32_t> classes;    // sharing set, ascending class ids
  int64_t wp = 0, yp = 0, wm = 0, ym = 0;  // fixed-point sums over S
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

struct RoundStats {
  int32_t round = 0;               // 0-based
  double cost_before = 0.0;        // exponential loss sum w before the update (after mining)
  double cost = 0.0;               // exponential loss sum w after the update
  double squared_error = 0.0;      // the paper's J of the fitted stump (weighted squared error)
  double gain = 0.0;               // squared-error reduction of sharing vs. constants only
  int32_t dim = -1;
  int32_t theta = 0;
  int32_t sharing_size = 0;
  double validation_p1 = -1.0;     // precision@1 on held-out samples; -1 = not evaluated
  double validation_p1_landmarks = -1.0;  // the same with the background class left out (no rejection)
  int64_t num_entries = 0;
  int64_t mined = 0;               // negatives added by mining at the start of this round
  double seconds = 0.0;            // whole round
  double seconds_histogram = 0.0;  // screening: column passes + per-class sums
  double seconds_search = 0.0;     // screening and refinement searches
  double seconds_update = 0.0;     // weights, scores, model
  double seconds_eval = 0.0;       // validation and mining
};

// F_m of a round: the k dims with the smallest counter_hash(seed, tag, round, dim), ascending.
// Independent of rank count and resume.
std::vector<int32_t> draw_round_dims(uint64_t seed, int32_t round, int32_t num_dims, int32_t k);

class SerialStumpLearner {
 public:
  // `features` rows are the samples of `set` (features.num_samples == set.num_samples()) and must
  // outlive the learner. Throws lmb::Error on bad options (options.check(num_dims)), a bad set
  // (set.check()), size mismatch, or features whose stored columns are all constant.
  SerialStumpLearner(const FeatureMatrix& features, const TrainingSet& set, const BoostOptions& options);
  virtual ~SerialStumpLearner() = default;
  SerialStumpLearner(const SerialStumpLearner&) = delete;
  SerialStumpLearner& operator=(const SerialStumpLearner&) = delete;

  // Bootstraps the negatives and sets every weight to 1. Called by the first round if not before.
  void initialize();
  // One boosting round. Throws lmb::Error if the weights stop being finite.
  RoundStats run_round();
  // Runs the remaining rounds; on_round sees each round's statistics.
  void train(const std::function<void(const RoundStats&)>& on_round = {});

  const BoostModel& model() const { return model_; }
  int32_t rounds_done() const { return static_cast<int32_t>(model_.stumps.size()); }
  const BoostOptions& options() const { return options_; }

  // The current entries with true weights (tests, checkpoints), sample-major order.
  struct Entry {
    int64_t sample = 0;
    int32_t cls = 0;
    int8_t z = 1;
    double weight = 0.0;
  };
  std::vector<Entry> entries() const;
  double exp_loss() const;  // sum of true weights
  // Precision@1 of the tracked validation samples under the current model.
  // exclude_background: best landmark class only (the top-1 ranking without rejection).
  // Collective in a distributed layer (every part holds some rows): call it on every rank.
  double validation_precision(bool exclude_background = false);

  // The search of one round without changing state (tests): best record over `dims` (global dims,
  // all stored here) with the current weights.
  StumpRecord search(const std::vector<int32_t>& dims);
  // The screening of those dims alone (tests): every (dim, theta) with a positive screening gain,
  // by ascending dim.
  std::vector<ScreenedCandidate> screen(std::vector<int32_t> dims);

 protected:
  // Hooks for a distributed layer.
  // This rank's share of the round's dims (default: all of them; each must be stored here).
  virtual std::vector<int32_t> choose_dims(int32_t round, const std::vector<int32_t>& round_dims);
  // Picks the candidates for the full search from this rank's screened ones (default: the
  // refine_top best by (gain, dim, theta)). A distributed layer gathers and picks globally.
  virtual std::vector<ScreenedCandidate> select_for_refinement(std::vector<ScreenedCandidate> local);
  // Combines the ranks' best records (default: identity).
  virtual StumpRecord reduce_best(StumpRecord local) { return local; }
  // above[s] = [v_dim(s) > theta] for every sample (default: reads the local column).
  virtual void stump_above(int32_t dim, int32_t theta, std::vector<uint8_t>* above);
  // Global reductions of per-rank scalars (default: identity).
  virtual double reduce_max(double local) { return local; }
  virtual int64_t reduce_sum(int64_t local) { return local; }
  // The per-class totals W_c, Y_c (2 x (C + 1) int64 per round), summed across ranks by a layer
  // that splits the entries (default: no-op). A feature-parallel layer (dims split, entries
  // replicated) needs none: every column pass sees all of a dim's samples, which the blocked
  // screening pass (screen_block) relies on.
  virtual void reduce_class_totals(std::vector<int64_t>* /*w*/, std::vector<int64_t>* /*y*/) {}
  // The tracked rows (validation and mining pool samples) split into parts: this process holds
  // and updates the scores of rows part, part + parts, ... only (work_part() = (part, parts), read
  // once by initialize() / restore_state()). sum_over_parts sums an integer over the parts;
  // gather_parts returns every part's bytes concatenated in part order on every part;
  // gather_parts_to_first hands part 0 every part's bytes, in part order, one at a time (the
  // other parts get no call). Default: one part.
  virtual std::pair<int, int> work_part() const { return {0, 1}; }
  virtual int64_t sum_over_parts(int64_t local) { return local; }
  virtual std::vector<uint8_t> gather_parts(const std::vector<uint8_t>& local) { return local; }
  virtual void gather_parts_to_first(const uint8_t* local, int64_t size,
                                     const std::function<void(int, const uint8_t*, int64_t)>& take) {
    take(0, local, size);
  }

  // Columns of dims stored on other ranks, lent to this one for the current round (to screen or
  // refine them here): pack_column(dim) on a rank that has the column (stored or lent) gives its
  // S bins and candidate thresholds, lend_column(dim, packed) on another makes it usable there.
  // Lent columns are dropped at the start of every round. Both throw lmb::Error (a dim not here,
  // a packed column of the wrong size or with invalid thresholds).
  std::vector<uint8_t> pack_column(int32_t dim) const;
  void lend_column(int32_t dim, std::vector<uint8_t> packed);
  // How a stored dim is screened: 0 never (constant column), 1 in the blocked class-major pass,
  // 2 by a column pass of its own.
  int screening_kind(int32_t dim) const;

  const FeatureMatrix& features_;
  const TrainingSet& set_;
  BoostOptions options_;

 private:
  struct DimLayout {
    std::vector<uint8_t> thresholds;  // ascending candidate thresholds
    uint8_t bucket[256];              // bucket of a bin: number of thresholds below it
    float above_fraction = 0.f;       // samples above the smallest threshold
  };
  // The candidate thresholds of a column of S bins (options_.screening.max_thresholds).
  DimLayout make_layout(const uint8_t* col) const;
  // bucket[] from the thresholds.
  static void fill_buckets(DimLayout* layout);
  // screening_kind of a column with this layout.
  int layout_kind(const DimLayout& layout) const;
  // A dim's column and layout, stored here or lent this round (column nullptr: neither).
  struct ColumnRef {
    int32_t dim = -1;
    const uint8_t* column = nullptr;
    const DimLayout* layout = nullptr;
  };
  ColumnRef column_ref(int32_t dim) const;
  struct LentColumn {
    int32_t dim;
    std::vector<uint8_t> column;
    DimLayout layout;
  };
  std::vector<LentColumn> lent_;
  void build_layouts();
  void bootstrap_negatives();
  void rebuild_entry_index(std::vector<int64_t>& samples, std::vector<int32_t>& codes,
                           std::vector<double>& weights);
  void quantize_weights();
  // Per (class, bucket) sums of one column into hist_ (sample-major).
  void scatter_dim(const uint8_t* col, const DimLayout& layout);
  void cumulate_hist(int32_t num_thresholds);
  // From the scattered histogram: touched_ and cum_p_/cum_n_; zeroes the histogram.
  int32_t collect_dim_sums(int32_t num_thresholds);
  // From the scattered histogram: screening gains per threshold; zeroes the histogram.
  void screen_scattered(int32_t num_thresholds, std::vector<double>* gains);
  // Screening gains of up to kBlockDims stored columns (each with at most 15 thresholds) in one
  // class-major pass over the entries: gains[k * 16 + t]. Equal, bit for bit, to scatter_dim +
  // screen_scattered on each column (the same sums in the same class order).
  static constexpr int kBlockDims = 8;
  void screen_block(const ColumnRef* refs, int32_t count, double* gains);
  // Fills wp_.. q_ and active_ with the touched classes that have weight above threshold t;
  // returns their number.
  int32_t prepare_threshold(int32_t num_touched, int32_t t, int32_t num_thresholds);
  StumpRecord search_impl(const std::vector<int32_t>& dims, RoundStats* stats);
  std::vector<ScreenedCandidate> screen_dims(const std::vector<int32_t>& sorted_dims, double* hist_seconds);
  int64_t mine_hard_negatives();
  void evaluate_validation(RoundStats* stats);
  // This part's validation rows: how many have their class ranked first with the background
  // competing (*all) and among the landmark classes only (*landmarks).
  void count_validation_hits(int64_t* all, int64_t* landmarks) const;
  // Rows of this part (local row i is global row row_part_ + i * row_parts_), and how many of
  // them are validation rows (they come first).
  int64_t local_rows() const;
  int64_t local_validation_rows() const;
  void split_rows();
  // Adds the pending stumps' outputs to this part's mining-pool rows, in round order (the same
  // float additions as one round at a time), and clears them.
  void flush_pool_rows();
  int32_t stored_index(int32_t dim) const;

  bool initialized_ = false;
  int32_t C1_ = 0;  // classes including background
  std::vector<int32_t> global_to_stored_;
  std::vector<DimLayout> layouts_;  // per stored column

  // Entries, sample-major.
  std::vector<int64_t> sample_offset_;  // size num_samples + 1
  std::vector<int32_t> entry_code_;     // class * 2 + (z < 0)
  std::vector<double> entry_weight_;    // stored weights; true = stored * 2^weight_exponent_
  // What the histogram pass reads, packed so that a sample's entries share cache lines.
  struct HotEntry {
    int64_t wq;    // this round's fixed-point weight
    int32_t code;  // class * 2 + (z < 0)
    int32_t unused;
  };
  std::vector<HotEntry> hot_;
  // The same entries class-major (positives, then negatives, each by ascending sample) for the
  // blocked screening pass: class c's are [class_begin_[c], class_begin_[c + 1]), its negatives
  // from class_neg_begin_[c]; class_index_[e] = where sample-major entry e sits here.
  std::vector<int64_t> class_begin_, class_neg_begin_, class_index_;
  std::vector<int32_t> class_sample_;
  std::vector<int64_t> class_wq_;
  std::vector<uint32_t> packed_buckets_;  // per sample: bucket of the block's k-th dim in bits 4k..4k+3
  int weight_exponent_ = 0;
  int quant_shift_ = 0;  // this round's fixed point: units = stored weight * 2^quant_shift_
  std::vector<std::vector<int64_t>> class_negatives_;  // per class: sorted negative samples
  std::vector<int64_t> class_w_, class_y_;             // per class fixed-point totals
  std::vector<double> class_q_;                        // Y^2 / W
  std::vector<double> negative_unit_;  // per class: initial weight of a negative (class balance)

  // Per-dim scratch.
  std::vector<int64_t> hist_;          // ((bucket - 1) * C1 + class) * 2 + neg; all zero between passes
  std::vector<std::pair<int32_t, int32_t>> nonzero_;  // (sample, bucket) of a column pass
  std::vector<int32_t> touched_;       // ascending class ids
  std::vector<int64_t> cum_p_, cum_n_;  // [t * touched + j]
  std::vector<int64_t> wp_, yp_, wm_, ym_;
  std::vector<double> wpd_, ypd_, wmd_, ymd_, q_;  // double copies for the screening pass
  std::vector<double> screen_gains_;
  std::vector<int32_t> active_;        // class of each search row
  std::vector<uint8_t> sharing_scratch_;

  // Tracked sample scores: score(s, c) = class_offset_[c] + tracked_scores_[i * C1 + c] for
  // this part's local row i (global row r = row_part_ + i * row_parts_, sample tracked_samples_[r]).
  std::vector<int64_t> tracked_samples_;  // every part's: validation rows first, then mining pool rows
  int64_t num_validation_rows_ = 0;
  int row_part_ = 0, row_parts_ = 1;
  std::vector<float> tracked_scores_;
  // Mining-pool rows are read only when mining: the stumps since the last flush wait here and are
  // added a row at a time (the row stays in cache) instead of streaming every row every round.
  struct PendingStump {
    std::vector<int32_t> classes;         // sharing set
    std::vector<float> d_above, d_below;  // per member: the output change above / below
    std::vector<uint8_t> above;           // per local pool row
  };
  std::vector<PendingStump> pending_pool_;
  std::vector<double> class_offset_;

  BoostModel model_;
  double last_validation_ = -1.0;

 public:
  // Everything that changes during training, for checkpoints (train/boost/learner_state.h).
  using State = LearnerState;
  // Initializes the learner first if no round ran yet. Collective in a distributed layer: the
  // tracked scores are gathered to part 0, whose State is complete; the other parts' States leave
  // tracked_scores empty.
  State save_state();
  // Throws lmb::Error when the state does not fit this learner's set and options (sizes, classes,
  // samples, dims out of range, more rounds than options().num_rounds).
  void restore_state(const State& state);
};

}  // namespace lmb
