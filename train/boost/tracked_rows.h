// The tracked rows: samples whose class scores the learner keeps up to date round by round,
// the held-out validation samples (precision@1) first, then the mining pool of training samples
// (hard-negative mining). score(s, c) = class_offset[c] + the row's stored score of c.
//
// The rows are split over the ranks of `comm` (rank r holds and updates rows r, r + R, ...; one
// process holds all), the largest per-class state of the learner. Mining-pool rows are read only
// when mining: the stumps since the last read wait and are added a row at a time (the row stays
// in cache) instead of streaming every pool row every round; the float additions are the same.
#pragma once

#include <cstdint>
#include <vector>

#include "train/boost/boost_options.h"
#include "train/boost/collectives.h"
#include "train/boost/learner_state.h"
#include "train/boost/training_set.h"

namespace lmb {

class TrackedRows {
 public:
  // `set` and `comm` must outlive this.
  TrackedRows(const TrainingSet& set, Collectives& comm);

  // Chooses the rows (seeded subsets): validation samples of landmark classes (none when
  // validation.interval is 0), then the mining pool (none when mining.interval is 0); scores 0.
  void select(const BoostOptions& options);

  // Adds a round's stump: d_above[j] / d_below[j] to class classes[j] of the rows whose sample has
  // above[s] / not (validation rows now, pool rows when next read).
  void add_stump(const std::vector<int32_t>& classes, std::vector<float> d_above, std::vector<float> d_below,
                 const std::vector<uint8_t>& above);
  // class_offset[c] += k[c].
  void add_constants(const std::vector<double>& k);
  const std::vector<double>& class_offset() const { return class_offset_; }

  int64_t num_validation_rows() const { return num_validation_rows_; }
  // Collective: precision@1 of the validation rows, with the background class competing
  // (*all) and among the landmark classes only (*landmarks); -1 without validation rows.
  void validation_precision(double* all, double* landmarks);

  // This rank's mining-pool rows with their scores up to date: fn(global row, sample, scores)
  // for each, by ascending row; scores[c] + class_offset()[c] is the score of class c.
  template <class Fn>
  void for_each_pool_row(const Fn& fn) {
    flush_pool();
    const int64_t V = num_validation_rows_, N = static_cast<int64_t>(samples_.size());
    const int64_t first = V <= part_ ? part_ : part_ + (V - part_ + parts_ - 1) / parts_ * parts_;
    for (int64_t r = first; r < N; r += parts_) {
      fn(r, samples_[r], scores_.data() + static_cast<size_t>((r - part_) / parts_) * C1_);
    }
  }
  int64_t sample(int64_t row) const { return samples_[row]; }

  // Collective: rank 0 gets every rank's rows (tracked_scores in global row order); the other
  // ranks leave tracked_scores empty.
  void save(LearnerState* state);
  // Throws lmb::Error when the state's rows do not fit the training set.
  void check(const LearnerState& state) const;
  void restore(const LearnerState& state);  // after check(): this rank's share of the rows

 private:
  int64_t local_rows() const;             // rows of this rank
  int64_t local_validation_rows() const;  // of which validation rows (they come first)
  void split();
  void flush_pool();
  // This rank's validation rows ranked correctly, with and without the background competing.
  void count_validation_hits(int64_t* all, int64_t* landmarks) const;

  const TrainingSet& set_;
  Collectives& comm_;
  int32_t C1_ = 0;
  std::vector<int64_t> samples_;  // every rank's rows: validation rows first, then the pool
  int64_t num_validation_rows_ = 0;
  int part_ = 0, parts_ = 1;   // local row i is global row part_ + i * parts_
  std::vector<float> scores_;  // local rows x C1
  std::vector<double> class_offset_;
  struct PendingStump {
    std::vector<int32_t> classes;         // sharing set
    std::vector<float> d_above, d_below;  // per member: the output change above / below
    std::vector<uint8_t> above;           // per local pool row
  };
  std::vector<PendingStump> pending_pool_;
};

}  // namespace lmb
