// The descriptor-matching baselines of `lboost eval` as matchers (train/eval/matcher.h): a k-NN
// index over the model's landmarks' training observations (train/eval/baselines.h,
// train/eval/faiss_index.h), its neighbours turned into ranked distinct landmarks, and optionally
// Lowe's ratio test deciding which best matches go to the pose estimator.
//
// Per frame, timed: one k-NN search of all the frame's descriptors (k = knn_k nearest
// observations), the ranking (each landmark at the rank of its nearest observation, score = minus
// that distance, at most top_k landmarks), and the ratio test. Without a ratio test every
// keypoint's best landmark is accepted (confidence = minus its distance).
//
// Ratio test (Lowe 2004): the best match (nearest observation, distance d1, landmark l1) is
// accepted when d1 < ratio * d2, strictly, where d2 is
//   - RatioNeighbor::kOtherLandmark: the distance of the nearest observation of ANOTHER landmark
//     than l1. A map observes each landmark several times, so the 2nd nearest observation is often
//     the same landmark again, and comparing against it rejects the most repeatable matches; the
//     test is meant to reject ambiguity between 3D points, so this is the variant for maps with
//     several descriptors per point. When none of the knn_k neighbours is another landmark: with
//     an exact index, d2 comes from a Hamming scan of every observation (the exact answer); with
//     an approximate one, d2 is taken as the k-th neighbour's distance, a lower bound (the match
//     is then accepted only when it passes against the bound);
//   - RatioNeighbor::kSecondObservation: the distance of the 2nd nearest observation, whatever its
//     landmark (OpenCV's knnMatch(k = 2) recipe applied to map observations).
// With no other observation at all (d2 undefined) the match is accepted. d1 = d2 = 0 rejects.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/landmark_map.h"
#include "train/eval/baselines.h"
#include "train/eval/matcher.h"

namespace lmb {

// A k-NN index over training observations.
class KnnIndex {
 public:
  virtual ~KnnIndex() = default;
  // For each of `num` descriptors (num * descriptor_bytes bytes): its k nearest observations,
  // sorted by (distance, index); fewer when the index holds fewer. k >= 1.
  virtual std::vector<std::vector<Neighbor>> search(const uint8_t* descriptors, int64_t num, int k) const = 0;
  virtual const TrainingObservations& observations() const = 0;
  // True when the neighbours are the exact k nearest by Hamming distance (a brute-force scan).
  virtual bool exact_hamming() const = 0;
  virtual nlohmann::json parameters() const { return nlohmann::json::object(); }
};

// BruteforceHamming (OpenCV BFMatcher or the popcount loop) as a KnnIndex.
class HammingKnnIndex : public KnnIndex {
 public:
  HammingKnnIndex(TrainingObservations observations, BruteforceHamming::Backend backend);
  std::vector<std::vector<Neighbor>> search(const uint8_t* descriptors, int64_t num, int k) const override;
  const TrainingObservations& observations() const override { return index_.observations(); }
  bool exact_hamming() const override { return true; }
  nlohmann::json parameters() const override;

 private:
  BruteforceHamming index_;
};

// ProjectedKdTree (exact Euclidean k-NN of PCA projections) as a KnnIndex.
class ProjectedKnnIndex : public KnnIndex {
 public:
  ProjectedKnnIndex(TrainingObservations observations, const ProjectedKdTreeOptions& options);
  std::vector<std::vector<Neighbor>> search(const uint8_t* descriptors, int64_t num, int k) const override;
  const TrainingObservations& observations() const override { return index_.observations(); }
  bool exact_hamming() const override { return false; }
  nlohmann::json parameters() const override;

 private:
  ProjectedKdTree index_;
};

enum class RatioNeighbor { kOtherLandmark, kSecondObservation };

struct DescriptorMatcherOptions {
  int top_k = 20;  // ranked landmarks kept per keypoint, >= 1
  int knn_k = 80;  // nearest observations searched per keypoint, >= top_k
  bool ratio_test = false;
  double ratio = 0.8;  // in (0, 1]
  RatioNeighbor ratio_neighbor = RatioNeighbor::kOtherLandmark;
  void check() const;  // throws lmb::Error naming the field
};

// Whether the best match of one keypoint's sorted neighbours (knn_k of them, or fewer when the
// index holds fewer) is accepted under `options` (the ratio test above, or none); false when there
// is no neighbour. `index` provides the exact scan for kOtherLandmark, which skips the landmarks
// for which `excluded` is true when it is given (the neighbours are then those of the other
// landmarks, see DescriptorMatcher::accepted_without). Exposed for tests.
bool passes_ratio_test(const std::vector<Neighbor>& neighbors, const uint8_t* descriptor, const KnnIndex& index,
                       const DescriptorMatcherOptions& options,
                       const std::function<bool(landmark_t)>& excluded = nullptr);

class DescriptorMatcher : public Matcher {
 public:
  // landmark_positions: the map's landmark positions (the correspondences' 3D points), indexed by
  // landmark id. Throws lmb::Error on a null index or invalid options.
  DescriptorMatcher(std::unique_ptr<KnnIndex> index, std::vector<Eigen::Vector3d> landmark_positions,
                    const DescriptorMatcherOptions& options);

  FrameMatches match(const EvalQuery& query) const override;
  // The knn_k nearest observations without those of excluded landmarks decide, as in match(); a
  // keypoint whose knn_k nearest observations are all of excluded landmarks gets no match.
  std::vector<Correspondence> accepted_without(const EvalQuery& query,
                                               const std::function<bool(landmark_t)>& excluded) const override;
  nlohmann::json parameters() const override;
  const KnnIndex& index() const { return *index_; }

 private:
  std::unique_ptr<KnnIndex> index_;
  std::vector<Eigen::Vector3d> landmark_positions_;
  DescriptorMatcherOptions options_;
};

}  // namespace lmb
