// The distributed JointBoost learner: the serial learner (train/boost/stump_learner.h) with its
// hooks over a Communicator, feature-parallel as LightGBM's feature-parallel learner.
//
// Partition: dim d belongs to rank d % R (round-robin, so each rank gets about |F_m| / R of every
// round's random draw, context dims and descriptor bits alike); a rank stores only its columns.
// Entries, weights, class totals, tracked scores and the model are replicated: every rank applies
// the same update from the same integers and the same `above` bits, so they stay identical.
//
// A round: every rank screens the F_m dims it owns with the replicated fixed-point weights; the
// screened (gain, dim, theta) lists are all-gathered and every rank picks the same global
// refine_top; each candidate is refined by its dim's owner; the ranks' best (gain, dim, theta)
// are all-gathered (16 bytes each), the best wins, and its rank broadcasts the record (fixed-point
// sums and sharing set) and the stump's `above` bits (S / 8 bytes).
// Each (dim, theta) is evaluated by exactly one rank with exactly the serial code on exactly the
// serial integers, so the model is bit-identical to the serial learner's for any rank count.
//
// Why dims and not classes: the screening and sharing-set searches sum doubles over the classes
// in class order; a class partition would have to combine those partial sums across ranks (a
// different rounding for each R) or ship every (class, threshold) histogram (16 bytes x C x T per
// candidate, ~1 MB per dim at 7,500 classes) to one rank. Per-class state is small (entries:
// ~1 M x 20 bytes at paper scale) next to the binned features (S x D bytes), which is what the dim
// partition divides.
//
// The per-round validation precision@1 (argmax over C + 1 classes of up to 4,096 held-out rows)
// is split: rank r scores rows r, r + R, ...; two integer allreduces sum the hits.
//
// Hard-negative mining runs on every rank on the replicated tracked scores (identical inputs give
// identical negatives, no communication); it costs pool x (C + 1) compares every mining_interval
// rounds (2,048 x 7,501 every 50 rounds at paper scale, ~0.2 ms a round).
#pragma once

#include <cstdint>
#include <vector>

#include "train/boost/stump_learner.h"
#include "train/dist/communicator.h"

namespace lmb {

// The global dims rank `rank` of `size` owns, ascending.
std::vector<int32_t> rank_dims(int32_t num_dims, int rank, int size);

class FeatureParallelLearner : public SerialStumpLearner {
 public:
  // `features` must store every dim this rank owns (it may store more, e.g. all); `comm` must
  // outlive the learner. Throws lmb::Error naming the first owned dim that is missing.
  FeatureParallelLearner(Communicator& comm, const FeatureMatrix& features, const TrainingSet& set,
                         const BoostOptions& options);

 protected:
  std::vector<int32_t> choose_dims(int32_t round, const std::vector<int32_t>& round_dims) override;
  std::vector<ScreenedCandidate> select_for_refinement(std::vector<ScreenedCandidate> local) override;
  StumpRecord reduce_best(StumpRecord local) override;
  void stump_above(int32_t dim, int32_t theta, std::vector<uint8_t>* above) override;
  // Validation rows are scored round-robin across ranks; the hit counts are summed (integers).
  std::pair<int, int> work_part() const override { return {comm_.rank(), comm_.size()}; }
  int64_t sum_over_parts(int64_t local) override { return comm_.allreduce_sum(local); }

 private:
  int owner(int32_t dim) const { return dim % comm_.size(); }
  Communicator& comm_;
};

}  // namespace lmb
