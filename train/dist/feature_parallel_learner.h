// The distributed JointBoost learner: the serial learner (train/boost/stump_learner.h) with three
// hooks over a Collectives (train/boost/collectives.h; MPI: train/dist/communicator.h),
// feature-parallel as LightGBM's feature-parallel learner.
//
// Partition: dim d belongs to rank d % R (train/dist/dim_partition.h); a rank stores only its
// columns. The tracked rows (validation and mining-pool samples x C + 1 scores, the largest
// per-class state: 184 MB at paper scale) are split by the serial learner's TrackedRows over the
// same ranks: rank r holds and updates rows r, r + R, ... Entries, weights and class totals are
// replicated: every rank applies the same update from the same integers and the same `above`
// bits, so they stay identical.
//
// A round:
// 1. choose_dims: the owners' blocked dims are balanced first: a rank above the least possible
//    maximum of 8-dim passes lends its highest dims' columns (S bytes each) to the ranks below it;
//    every rank screens the dims it owns or was lent with the replicated fixed-point weights.
// 2. select_for_refinement: the screened (gain, dim, theta) lists are all-gathered and every rank
//    picks the same global refine_top. The candidate dims are spread for refinement by estimated
//    cost, most expensive first to the least loaded rank, the column travelling when needed.
// 3. reduce_best: the ranks' best (gain, dim, theta) are all-gathered (16 bytes each), the best
//    wins, and its rank broadcasts the record (fixed-point sums and sharing set) and the stump's
//    `above` bits (S / 8 bytes) from the column it refined.
// Each (dim, theta) is evaluated by exactly one rank with exactly the serial code on exactly the
// serial integers, so the model is bit-identical to the serial learner's for any rank count.
//
// Why dims and not classes: the screening and sharing-set searches sum doubles over the classes
// in class order; a class partition would have to combine those partial sums across ranks (a
// different rounding for each R) or ship every (class, threshold) histogram (16 bytes x C x T per
// candidate, ~1 MB per dim at 7,500 classes) to one rank. The replicated per-class state is small
// (entries: ~1 M x 40 bytes at paper scale) next to the binned features (S x D bytes), which the
// dim partition divides.
//
// The per-round validation precision@1 is computed by each rank on its rows; two integer
// allreduces sum the hits. Hard-negative mining: each rank ranks the classes of its pool rows,
// the offers (16 bytes each) are all-gathered, and every rank admits them in row order with the
// same caps, so the negative sets stay identical.
#pragma once

#include <cstdint>
#include <vector>

#include "train/boost/collectives.h"
#include "train/boost/stump_learner.h"
#include "train/dist/dim_partition.h"

namespace lmb {

class FeatureParallelLearner : public SerialStumpLearner {
 public:
  // `features` must store every dim this rank owns (it may store more, e.g. all); `comm` must
  // outlive the learner. Collective. Throws lmb::Error naming the first owned dim that is missing.
  FeatureParallelLearner(Collectives& comm, const FeatureMatrix& features, const TrainingSet& set,
                         const BoostOptions& options);

 protected:
  std::vector<int32_t> choose_dims(int32_t round, const std::vector<int32_t>& round_dims) override;
  std::vector<ScreenedCandidate> select_for_refinement(std::vector<ScreenedCandidate> local) override;
  StumpRecord reduce_best(StumpRecord local, std::vector<uint8_t>* above) override;

 private:
  // Column transfers, done in list order by the two ranks concerned (tag = index).
  void move_columns(const std::vector<ColumnMove>& moves);

  std::vector<uint8_t> kind_;  // per dim: FeatureColumns::Kind, from its owner
  ScreeningPlan screening_;    // this round's
};

}  // namespace lmb
