#include "train/eval/descriptor_matchers.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "common/error.h"
#include "common/hamming.h"
#include "train/eval/timing.h"

namespace lmb {

HammingKnnIndex::HammingKnnIndex(TrainingObservations observations, BruteforceHamming::Backend backend)
    : index_(std::move(observations), backend) {}

std::vector<std::vector<Neighbor>> HammingKnnIndex::search(const uint8_t* descriptors, int64_t num, int k) const {
  return index_.knn_batch(descriptors, num, k);
}

nlohmann::json HammingKnnIndex::parameters() const {
  return {{"index", "exact Hamming"},
          {"backend", index_.backend() == BruteforceHamming::Backend::kOpenCv ? "opencv" : "popcount"}};
}

ProjectedKnnIndex::ProjectedKnnIndex(TrainingObservations observations, const ProjectedKdTreeOptions& options)
    : index_(std::move(observations), options) {}

std::vector<std::vector<Neighbor>> ProjectedKnnIndex::search(const uint8_t* descriptors, int64_t num, int k) const {
  std::vector<std::vector<Neighbor>> out(static_cast<size_t>(std::max<int64_t>(num, 0)));
  const int bytes = index_.observations().descriptor_bytes;
  for (int64_t q = 0; q < num; ++q) out[static_cast<size_t>(q)] = index_.knn(descriptors + q * bytes, k);
  return out;
}

nlohmann::json ProjectedKnnIndex::parameters() const {
  return {{"index", "exact k-NN of PCA projections (kd-tree)"}, {"pca_dims", index_.dims()}};
}

void DescriptorMatcherOptions::check() const {
  LMB_CHECK(top_k >= 1, "DescriptorMatcherOptions: top_k " << top_k << " must be >= 1");
  LMB_CHECK(knn_k >= top_k, "DescriptorMatcherOptions: knn_k " << knn_k << " must be >= top_k " << top_k);
  LMB_CHECK(!ratio_test || knn_k >= 2,
            "DescriptorMatcherOptions: knn_k " << knn_k << " must be >= 2 for the ratio test");
  LMB_CHECK(std::isfinite(ratio) && ratio > 0.0 && ratio <= 1.0,
            "DescriptorMatcherOptions: ratio " << ratio << " must be in (0, 1]");
}

namespace {

// The Hamming distance of the nearest observation of another landmark than `exclude` (and none
// for which `excluded` is true, when given), +inf when there is none.
double nearest_other_landmark(const uint8_t* descriptor, const TrainingObservations& obs, landmark_t exclude,
                              const std::function<bool(landmark_t)>& excluded) {
  double best = std::numeric_limits<double>::infinity();
  for (int64_t i = 0; i < obs.size(); ++i) {
    const landmark_t l = obs.landmark[static_cast<size_t>(i)];
    if (l == exclude || (excluded && excluded(l))) continue;
    best = std::min(best, static_cast<double>(hamming_distance(descriptor, obs.descriptor(i), obs.descriptor_bytes)));
  }
  return best;
}

}  // namespace

bool passes_ratio_test(const std::vector<Neighbor>& nn, const uint8_t* descriptor, const KnnIndex& index,
                       const DescriptorMatcherOptions& options, const std::function<bool(landmark_t)>& excluded) {
  if (nn.empty()) return false;
  if (!options.ratio_test) return true;
  const std::vector<landmark_t>& landmark = index.observations().landmark;
  const double d1 = nn[0].distance;
  double d2 = std::numeric_limits<double>::infinity();
  if (options.ratio_neighbor == RatioNeighbor::kSecondObservation) {
    if (nn.size() >= 2) d2 = nn[1].distance;  // knn_k >= 2: fewer only when there is no other observation
  } else {
    const landmark_t l1 = landmark[static_cast<size_t>(nn[0].index)];
    bool found = false;
    for (const Neighbor& n : nn) {
      if (landmark[static_cast<size_t>(n.index)] != l1) {
        d2 = n.distance;
        found = true;
        break;
      }
    }
    // Not among the neighbours: farther than all of them, or no other landmark at all.
    const bool truncated = static_cast<int64_t>(nn.size()) < index.observations().size();
    if (!found && truncated) {
      d2 = index.exact_hamming() ? nearest_other_landmark(descriptor, index.observations(), l1, excluded)
                                 : nn.back().distance;
    }
  }
  if (std::isinf(d2)) return true;  // no competitor
  return d1 < options.ratio * d2;
}

DescriptorMatcher::DescriptorMatcher(std::unique_ptr<KnnIndex> index, std::vector<Eigen::Vector3d> landmark_positions,
                                     const DescriptorMatcherOptions& options)
    : index_(std::move(index)), landmark_positions_(std::move(landmark_positions)), options_(options) {
  LMB_CHECK(index_ != nullptr, "DescriptorMatcher: null index");
  options_.check();
  for (landmark_t l : index_->observations().landmark) {
    LMB_CHECK(l >= 0 && static_cast<size_t>(l) < landmark_positions_.size(),
              "DescriptorMatcher: observation of landmark " << l << " but " << landmark_positions_.size()
                                                            << " landmark positions");
  }
}

FrameMatches DescriptorMatcher::match(const EvalQuery& q) const {
  const int64_t n = static_cast<int64_t>(q.keypoints.size());
  const int bytes = index_->observations().descriptor_bytes;
  FrameMatches r;
  const double c0 = thread_cpu_ms();
  const Clock::time_point t0 = Clock::now();
  const std::vector<std::vector<Neighbor>> nn = index_->search(q.descriptors, n, options_.knn_k);
  r.ranking.resize(static_cast<size_t>(n));
  std::vector<char> accept(static_cast<size_t>(n), 0);
  for (int64_t k = 0; k < n && static_cast<size_t>(k) < nn.size(); ++k) {
    std::vector<RankedCandidate>& c = r.ranking[static_cast<size_t>(k)];
    c = neighbors_to_candidates(nn[static_cast<size_t>(k)], index_->observations().landmark);
    if (c.size() > static_cast<size_t>(options_.top_k)) c.resize(static_cast<size_t>(options_.top_k));
    accept[static_cast<size_t>(k)] =
        passes_ratio_test(nn[static_cast<size_t>(k)], q.descriptors + k * bytes, *index_, options_);
  }
  r.match_ms = ms_since(t0);
  r.cpu_ms = thread_cpu_ms() - c0;
  for (int64_t k = 0; k < n; ++k) {
    if (!accept[static_cast<size_t>(k)]) continue;
    const RankedCandidate& best = r.ranking[static_cast<size_t>(k)][0];
    r.accepted.push_back(Correspondence{static_cast<int32_t>(k), best.landmark,
                                        landmark_positions_[static_cast<size_t>(best.landmark)], best.score});
  }
  return r;
}

std::vector<Correspondence> DescriptorMatcher::accepted_without(const EvalQuery& q,
                                                                const std::function<bool(landmark_t)>& excluded) const {
  const int64_t n = static_cast<int64_t>(q.keypoints.size());
  const int bytes = index_->observations().descriptor_bytes;
  const std::vector<landmark_t>& landmark = index_->observations().landmark;
  const std::vector<std::vector<Neighbor>> nn = index_->search(q.descriptors, n, options_.knn_k);
  std::vector<Correspondence> out;
  for (int64_t k = 0; k < n && static_cast<size_t>(k) < nn.size(); ++k) {
    std::vector<Neighbor> kept;
    for (const Neighbor& x : nn[static_cast<size_t>(k)]) {
      if (!excluded(landmark[static_cast<size_t>(x.index)])) kept.push_back(x);
    }
    if (!passes_ratio_test(kept, q.descriptors + k * bytes, *index_, options_, excluded)) continue;
    const landmark_t best = landmark[static_cast<size_t>(kept[0].index)];
    out.push_back(Correspondence{static_cast<int32_t>(k), best, landmark_positions_[static_cast<size_t>(best)],
                                 -static_cast<double>(kept[0].distance)});
  }
  return out;
}

nlohmann::json DescriptorMatcher::parameters() const {
  nlohmann::json p = index_->parameters();
  p["top_k"] = options_.top_k;
  p["knn_k"] = options_.knn_k;
  if (options_.ratio_test) {
    p["ratio"] = options_.ratio;
    p["ratio_second_neighbor"] =
        options_.ratio_neighbor == RatioNeighbor::kOtherLandmark ? "other_landmark" : "second_observation";
  }
  return p;
}

}  // namespace lmb
