// The distributed JointBoost learner: the serial learner (train/boost/stump_learner.h) with its
// hooks over a Communicator, feature-parallel as LightGBM's feature-parallel learner.
//
// Partition: dim d belongs to rank d % R (round-robin, so each rank gets about |F_m| / R of every
// round's random draw, context dims and descriptor bits alike); a rank stores only its columns.
// The tracked rows (validation and mining-pool samples x C + 1 scores, the largest per-class
// state: 184 MB at paper scale) are split too: rank r holds and updates rows r, r + R, ...
// Entries, weights and class totals are replicated: every rank applies the same update from the
// same integers and the same `above` bits, so they stay identical.
//
// A round:
// 1. Screening: the owners' blocked dims are balanced first: a rank above the least possible
//    maximum of 8-dim passes lends its highest dims' columns (S bytes each) to the ranks below
//    it; every rank screens the dims it owns or was lent with the replicated fixed-point weights.
// 2. The screened (gain, dim, theta) lists are all-gathered and every rank picks the same global
//    refine_top. The candidate dims are spread for refinement by estimated cost (a column pass
//    over the dim's non-zero samples plus a sharing-set search per threshold), most expensive
//    first to the least loaded rank, the column travelling to it when needed.
// 3. The ranks' best (gain, dim, theta) are all-gathered (16 bytes each), the best wins, and its
//    rank broadcasts the record (fixed-point sums and sharing set); the dim's owner broadcasts
//    the stump's `above` bits (S / 8 bytes).
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
// The per-round validation precision@1 (argmax over C + 1 classes of up to 4,096 held-out rows)
// is computed by each rank on its rows; two integer allreduces sum the hits. Hard-negative mining
// (every mining_interval rounds): each rank ranks the classes of its pool rows, the offers
// (row, class, score: 16 bytes each) are all-gathered, and every rank admits them in row order
// with the same caps, so the negative sets stay identical.
#pragma once

#include <cstdint>
#include <utility>
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
  std::vector<uint8_t> gather_parts(const std::vector<uint8_t>& local) override;
  void gather_parts_to_first(const uint8_t* local, int64_t size,
                             const std::function<void(int, const uint8_t*, int64_t)>& take) override;

 private:
  int owner(int32_t dim) const { return dim % comm_.size(); }
  // The rank that screens `dim` this round (its owner, or the rank it was lent to).
  int screener(int32_t dim) const;
  // Column transfers, S bytes each, done in list order by the two ranks concerned.
  struct Move {
    int32_t dim;
    int from, to;
  };
  void move_columns(const std::vector<Move>& moves);

  Communicator& comm_;
  std::vector<uint8_t> kind_;                          // per dim: SerialStumpLearner::screening_kind
  std::vector<std::pair<int32_t, int>> screener_;      // this round's (dim, screening rank)
};

}  // namespace lmb
