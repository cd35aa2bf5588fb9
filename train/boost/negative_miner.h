// The negative sets L-_c: bootstrapped before the first round, through the visual words (the
// training samples that share a word with one of c's positives, seeded), then grown every
// mining.interval rounds by hard negatives from the tracked mining pool: a pool sample joins L-_c
// of the classes that score at or above its true class (best first, at most mining.per_sample), up
// to negatives.max_per_class, never closer to c's landmark than negatives.exclusion_radius.
//
// A negative's initial weight is its class's negative unit (class balance: the negatives of a
// class weigh negatives.weight_ratio times its positives) times the sample weight; a mined one
// starts with the weight it would have had in L-_c from the start, exp(H(s, c)) times that.
#pragma once

#include <cstdint>
#include <vector>

#include "train/boost/boost_options.h"
#include "train/boost/collectives.h"
#include "train/boost/entry_store.h"
#include "train/boost/learner_state.h"
#include "train/boost/tracked_rows.h"
#include "train/boost/training_set.h"

namespace lmb {

class NegativeMiner {
 public:
  // `set` and `options` must outlive this.
  NegativeMiner(const TrainingSet& set, const BoostOptions& options);

  // Every training sample as a positive of its class and the bootstrapped negatives of every
  // class, all weights initial, into `entries`.
  void bootstrap(EntryStore* entries);
  // Collective: every rank offers the hard negatives of its pool rows, every rank admits all
  // offers in row order with the same caps. Returns the number of entries added.
  int64_t mine(TrackedRows& rows, Collectives& comm, EntryStore* entries);

  void save(LearnerState* state) const { state->negative_unit = negative_unit_; }
  // Throws lmb::Error unless there is one finite positive unit per class.
  void check(const LearnerState& state) const;
  void restore(const LearnerState& state) { negative_unit_ = state.negative_unit; }

 private:
  // Offer: pool row `row` as a negative of `cls` at score `score`.
  struct Offer {
    int64_t row;
    int32_t cls;
    float score;
  };
  // This rank's offers: per pool row the classes ranked at or above its true class, best first.
  std::vector<Offer> pool_offers(TrackedRows& rows) const;
  // n_neg seeded negatives of class c among the samples of `lists`, ascending.
  std::vector<int64_t> draw(int32_t c, const std::vector<const std::vector<int64_t>*>& lists, int32_t n_neg) const;
  // Never a negative of c: a sample whose position lies within exclusion_radius of c's landmark.
  bool excluded(int32_t c, int64_t s) const;
  double sample_weight(int64_t s) const;

  const TrainingSet& set_;
  const BoostOptions& options_;
  int32_t C1_ = 0;
  std::vector<double> negative_unit_;  // per class: initial weight of a negative (class balance)
};

}  // namespace lmb
