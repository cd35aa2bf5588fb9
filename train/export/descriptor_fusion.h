// The descriptor-distance fusion of an exported model (infer/model.h DescriptorFusion): a landmark
// class's score becomes H(v, c) + distance_score[d_c(v)], d_c the Hamming distance from the
// keypoint's descriptor to the nearest of class c's exemplars (its map observations). Stumps on
// single descriptor bits approximate a Hamming distance poorly; this term gives the classifier the
// descriptor's own nearest-neighbour evidence, which it must not lose to, and leaves to the stumps
// (context and bits) what the distance cannot tell apart.
//
// How it is fitted, on the map's training side only (never on query frames):
//   1. The shape: the log-likelihood ratio of the distance,
//        g(d) = log P(d_c = d | the keypoint is c) - log P(d_c = d | it is not c),
//      from training observations (leave-one-out: a sample's own row is no exemplar), in bins of
//      bin_width bits (counts + 0.5), made non-increasing in d (pool-adjacent-violators, weighted
//      by the bin counts), linear between bin centres.
//   2. The weight: distance_score = alpha * g with alpha from `weights` maximising precision@1 over
//      the held-out map observations (TrainingSet validation samples, leave-one-out distances
//      again), the classifier's exact scores H (the inference library's sums) ranked with the same
//      tie rule as the Classifier; P@1 is averaged over each weight and its grid neighbours first
//      (a plateau's middle, not its edge), ties to the smaller weight.
// The exemplars stored in the model: every non-query map observation of each class (the
// observations the Hamming baseline of `lboost eval` searches), or, with max_exemplars > 0, at most
// that many a class chosen by greedy k-centre in Hamming space (k_centre_exemplars) among its
// observations outside the held-out ones; the shape and the weight are then fitted with the
// exemplars kept, the ones inference searches. Deterministic:
// subsets come from a seeded hash or a fixed tie rule, every sum runs in a fixed order.
#pragma once

#include <cstdint>
#include <vector>

#include "common/landmark_map.h"
#include "infer/model.h"
#include "train/boost/training_set.h"

namespace lmb {

struct DescriptorFusionOptions {
  int32_t bin_width = 8;                // Hamming bits per likelihood-ratio bin, 1..64
  int32_t max_distance_samples = 4096;  // training observations for g (seeded subset)
  int32_t max_fit_samples = 4096;       // held-out observations for alpha (seeded subset)
  // Exemplars kept a class, >= 0; 0 = every map observation. Fewer exemplars make a smaller model
  // and fewer descriptor comparisons a scored class (docs/matching.md: the cost and the P@1 lost).
  int32_t max_exemplars = 0;
  // Candidate weights alpha, ascending, >= 0; 0 = no fusion term.
  std::vector<double> weights = {0.0,   0.0625, 0.125, 0.1875, 0.25, 0.3125, 0.375, 0.4375, 0.5,
                                 0.625, 0.75,   0.875, 1.0,    1.25, 1.5,    2.0,   3.0,    4.0};
  uint64_t seed = 1;
  // Throws lmb::Error naming the field.
  void check() const;
};

struct DescriptorFusionStats {
  double weight = 0.0;                 // the chosen alpha
  int64_t exemplars = 0;               // rows stored in the model
  int64_t distance_samples = 0;        // training observations behind g
  int64_t fit_samples = 0;             // held-out observations behind alpha
  double fit_p1_without = 0.0;         // their P@1 with alpha = 0 (the stump sums alone)
  double fit_p1_with = 0.0;            // with the chosen alpha
  double fit_p1_hamming = 0.0;         // nearest exemplar alone (ties: the larger H)
  std::vector<double> weight_p1;       // P@1 of every candidate weight (options.weights order)
  std::vector<double> log_ratio;       // g at the bin centres, after the monotone fit
  std::vector<double> distance_ratio;  // g at every distance 0..8 * descriptor bytes
};

// The map keypoints whose descriptors are class c's exemplars, in the order the model stores them:
// every observation of class_landmarks[c] in the map's non-query frames, in keypoint order (empty
// for a class with none). Throws lmb::Error for a landmark not in the map.
std::vector<std::vector<int64_t>> exemplar_keypoints(const LandmarkMap& map,
                                                     const std::vector<landmark_t>& class_landmarks);

// The `cap` of `keypoints` (map keypoints of one class, ascending) kept as its exemplars: all of
// them when cap is 0 or they are no more; else greedy k-centre in Hamming space: the medoid (the
// smallest sum of distances to the others; ties: the first), then, one at a time, the keypoint
// farthest from those chosen (its distance to the nearest of them; ties: the first) until `cap`
// are chosen. Returned ascending. Deterministic.
std::vector<int64_t> k_centre_exemplars(const LandmarkMap& map, const std::vector<int64_t>& keypoints, int32_t cap);

// Fits the fusion of `model` (a model without one, exported from the run that trained on `set`;
// set.class_landmark must equal the model's classes) and returns it. Throws lmb::Error when the
// set and the model disagree, a class has no map observation, or there is no held-out sample or
// no training observation with a second one of its class.
DescriptorFusion fit_descriptor_fusion(const Model& model, const LandmarkMap& map, const TrainingSet& set,
                                       const DescriptorFusionOptions& options, DescriptorFusionStats* stats = nullptr);

}  // namespace lmb
