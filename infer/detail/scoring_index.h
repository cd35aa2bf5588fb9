// Internal (not installed): the scoring indices of an inference Model, which the classifier
// (infer/classifier.h), the trainer's export and the tests read through Model::scoring(). Built
// once from the model's data when the Model is constructed, immutable afterwards.
#pragma once

#include <cstdint>
#include <vector>

#include "common/context_embedding.h"
#include "infer/model.h"
#include "infer/simd/scoring_kernels.h"

namespace lmb::detail {

// The feature layout of a model's context dims and descriptor bits (common/context_embedding.h).
inline EmbeddingLayout layout_of(const ModelData& data) {
  EmbeddingLayout l;
  l.num_regions = data.regions.size();
  l.num_words = data.vocabulary.num_words();
  l.descriptor_bytes = data.descriptor_bytes;
  return l;
}

// Descriptor-distance fusion (DescriptorFusion, infer/model.h): the term of class cls (< C) for a
// descriptor of model.descriptor_bytes() bytes; 0 without fusion.
double fusion_term(const Model& model, int32_t cls, const uint8_t* descriptor);
// fusion_term of class cls (the model has a fusion) for the descriptors (contiguous rows) of the
// set bits j of `lanes`: out[j] (the other entries untouched); distance: 32 scratch entries.
void fusion_terms(const Model& model, int32_t cls, const uint8_t* descriptors, uint32_t lanes, int32_t* distance,
                  double* out);
// An upper bound of fusion_term of class cls for the descriptors of the set bits j of `lanes`
// (out[j], the other entries untouched), from the distances to the class's fusion balls
// (ScoringIndex::fusion_ball_begin) instead of to every exemplar; false (out untouched) when the
// class has no balls. distance: 32 scratch entries.
bool fusion_term_bounds(const Model& model, int32_t cls, const uint8_t* descriptors, uint32_t lanes, int32_t* distance,
                        double* out);

class ScoringIndex {
 public:
  // `data` must have passed ModelData::check().
  explicit ScoringIndex(const ModelData& data);

  const EmbeddingLayout& layout() const { return layout_; }

  // The feature dimensions any stump reads, ascending ("used dims"); stump m reads used dim
  // dense_stumps()[m].used (an index into used_dims()).
  const std::vector<int32_t>& used_dims() const { return used_dims_; }
  // used_dims() prepared for FrameContext::compute_dims.
  const DimPlan& used_plan() const { return used_plan_; }

  // Dense scoring: stumps as flat arrays (used: index into used_dims(); above = a + b, below = b),
  // sharing sets in CSR form.
  const std::vector<DenseStump>& dense_stumps() const { return dense_stumps_; }
  const std::vector<int64_t>& stump_class_begin() const { return stump_class_begin_; }  // M + 1
  const std::vector<int32_t>& stump_classes() const { return stump_classes_; }

  // Per-class scoring (inverted file): class c's stumps in training order are entries
  // [class_stump_begin()[c], class_stump_begin()[c + 1]) of class_stumps(); the same DenseStump
  // records, copied so that one class's loop reads contiguous memory.
  const std::vector<int64_t>& class_stump_begin() const { return class_stump_begin_; }  // C + 2
  const std::vector<DenseStump>& class_stumps() const { return class_stumps_; }
  // The same entries as stump indices (into dense_stumps()), for the batched classifier.
  const std::vector<int32_t>& class_stump_index() const { return class_stump_index_; }

  // Inverted file in CSR form: word w's candidate classes are [word_class_begin()[w],
  // word_class_begin()[w + 1]) of word_classes(), ascending.
  const std::vector<int32_t>& word_class_begin() const { return word_class_begin_; }
  const std::vector<int32_t>& word_classes() const { return word_classes_; }
  // The used dims that word w's candidate classes and the background read: indices into
  // used_dims(), ascending, in [word_used_begin()[w], word_used_begin()[w + 1]) of word_used();
  // word_used_dims() holds the matching global dims (what FrameContext::compute_dims takes).
  const std::vector<int32_t>& word_used_begin() const { return word_used_begin_; }
  const std::vector<int32_t>& word_used() const { return word_used_; }
  const std::vector<int32_t>& word_used_dims() const { return word_used_dims_; }
  // Word w's used dims prepared for FrameContext::compute_dims.
  const DimPlan& word_plan(int32_t w) const { return word_plans_[w]; }

  // The largest fusion term any descriptor can get (0 without fusion; the screening adds it to
  // every bound).
  double fusion_max() const { return fusion_term_bound_.empty() ? 0.0 : fusion_term_bound_.front(); }
  // Fusion balls: class c's n exemplars, when it has at least kMinBallExemplars of them, are
  // covered by ceil(sqrt(2 n)) balls (greedy k-centre in Hamming space from its first exemplar, each
  // exemplar in the ball of its nearest centre): balls [fusion_ball_begin()[c],
  // fusion_ball_begin()[c + 1]) (C + 1 offsets; none for a class with fewer exemplars), centre b
  // the row b of fusion_ball_centres() (descriptor_bytes each), every exemplar of the ball within
  // fusion_ball_radius()[b] bits of it. So a descriptor q is at least
  // min_b max(0, d(q, centre_b) - radius_b) from every exemplar of c (the triangle inequality), and
  // its term is at most fusion_term_bound()[that] (the largest distance_score at that distance or
  // beyond: 8 * descriptor_bytes + 1 entries). Empty without fusion.
  static constexpr int64_t kMinBallExemplars = 8;
  const std::vector<int64_t>& fusion_ball_begin() const { return fusion_ball_begin_; }
  const std::vector<uint8_t>& fusion_ball_centres() const { return fusion_ball_centres_; }
  const std::vector<int32_t>& fusion_ball_radius() const { return fusion_ball_radius_; }
  const std::vector<double>& fusion_term_bound() const { return fusion_term_bound_; }

  // Screening (an upper bound of a landmark class's score from 16-bit integer sums, so that the
  // classifier skips, without computing its exact score, a class that cannot be a match):
  //   stump m's step a_m = above - below is rounded to q_m = round(a_m / step), step a power of
  //   two chosen so that |q_m| <= 32767 and each class's sum of |q_m| <= 65535;
  //   Q = sum over the class's stumps of (fires ? q_m : 0), summed modulo 2^16 (uint16 lanes),
  //   is recovered from its residue t = (Q - low_c) mod 2^16 because Q lies in
  //   [low_c, low_c + 65535] (low_c = sum of the negative q_m);
  //   bound = offset_c + step * t >= the class's exact score (the double the trainer sums) for
  //   every input, where offset_c = bias_c + sum of below_m + sum of max(0, a_m - step * q_m)
  //   + step * low_c + a margin covering every rounding error (scoring_index.cc proves it).
  // The integer sum does not depend on the order, so each class's screening list holds its stumps
  // by decreasing |q_m| (ties: training order), as uint16 stump indices (screening needs
  // M <= 65536 stumps; with more, every bound is +inf and every class is scored exactly).
  // Checkpoints, after every kScreenCheck entries of that list (k = 1, 2, ... while entries
  // remain): the sum Q_k of the first k kScreenCheck entries is recovered likewise from its
  // residue t_k = (Q_k - low_ck) mod 2^16 (low_ck = the sum of their negative q_m), and
  //   bound_k = offset_c + step * (t_k + add_ck) >= the class's exact score, where
  //   add_ck = low_ck - low_c + the sum of the positive q_m of the remaining entries;
  // a class whose bound_k already fails in every lane is dropped there.
  // The tests run in integers (detail::screen_goals in classifier.h): a lane whose double test
  //   bound - background > min_margin and bound >= min_score
  // passes also passes x + units_c + 2 >= goal_j, x = t + add (the multiple of step in bound),
  // units_c = ceil(offset_c / step) clamped to +-kScreenUnitsLimit, and goal_j =
  // floor(max(background_j + min_margin, min_score) / step). Why: while |background_j|,
  // |min_margin| and |min_score| are at most 2^27 steps (else goal_j = kScreenPassAll, the lane
  // is never dropped) and |offset_c| at most 2^29 steps, each double rounding moves the test by
  // less than 2^-20 steps, and ceil / floor only loosen it; an offset_c beyond -2^29 steps fails
  // the double test anyway, and one beyond +2^29 steps (or +inf) passes the integer one always.
  static constexpr int32_t kScreenCheck = detail::kScreenCheck;
  static constexpr int32_t kScreenUnitsLimit = 1 << 29;
  static constexpr int32_t kScreenPassAll = -(1 << 29) - 2;  // a goal every lane passes
  double screen_step() const { return screen_step_; }
  const std::vector<int16_t>& screen_q() const { return screen_q_; }           // M
  const std::vector<double>& screen_offset() const { return screen_offset_; }  // C
  const std::vector<int32_t>& screen_units() const { return screen_units_; }   // C
  const std::vector<uint16_t>& screen_low() const { return screen_low_; }      // C: low_c mod 2^16
  // Class c's screening list: entries [class_stump_begin()[c], class_stump_begin()[c + 1]).
  const std::vector<uint16_t>& screen_list() const { return screen_list_; }
  // Class c's checkpoints are entries [screen_check_begin()[c], screen_check_begin()[c + 1]) of
  // screen_check_low() (low_ck mod 2^16) and screen_check_add() (add_ck).
  const std::vector<int64_t>& screen_check_begin() const { return screen_check_begin_; }  // C + 1
  const std::vector<uint16_t>& screen_check_low() const { return screen_check_low_; }
  const std::vector<int32_t>& screen_check_add() const { return screen_check_add_; }

 private:
  EmbeddingLayout layout_;
  std::vector<int32_t> used_dims_;
  std::vector<DenseStump> dense_stumps_;
  std::vector<int64_t> stump_class_begin_;
  std::vector<int32_t> stump_classes_;
  std::vector<int64_t> class_stump_begin_;
  std::vector<DenseStump> class_stumps_;
  std::vector<int32_t> class_stump_index_;
  std::vector<int32_t> word_class_begin_;
  std::vector<int32_t> word_classes_;
  std::vector<int32_t> word_used_begin_;
  std::vector<int32_t> word_used_;
  std::vector<int32_t> word_used_dims_;
  DimPlan used_plan_;
  std::vector<DimPlan> word_plans_;
  std::vector<int64_t> fusion_ball_begin_;
  std::vector<uint8_t> fusion_ball_centres_;
  std::vector<int32_t> fusion_ball_radius_;
  std::vector<double> fusion_term_bound_;
  double screen_step_ = 1.0;
  std::vector<int16_t> screen_q_;
  std::vector<double> screen_offset_;
  std::vector<int32_t> screen_units_;
  std::vector<uint16_t> screen_low_;
  std::vector<uint16_t> screen_list_;
  std::vector<int64_t> screen_check_begin_;
  std::vector<uint16_t> screen_check_low_;
  std::vector<int32_t> screen_check_add_;

  void build_screen(const ModelData& data);
  void build_fusion_balls(const ModelData& data);
};

}  // namespace lmb::detail
