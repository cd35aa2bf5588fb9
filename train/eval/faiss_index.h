// A binary approximate nearest-neighbour index from faiss (Debian libfaiss-dev) for the
// `faiss_hnsw_ratio` baseline of `lboost eval`: faiss::IndexBinaryHNSW over the training
// observations' descriptors, searched with Hamming distances. The speed anchor among the
// baselines: what a practitioner reaches for when brute force is too slow.
//
// faiss runs on one thread here (the constructor sets OpenMP's thread count to 1): the graph is
// then built in a fixed order, so the index and every search are deterministic, and searches are
// single-thread like every other method's. faiss stays out of the inference library: only
// lmb_eval links it.
#pragma once

#include <memory>

#include <nlohmann/json.hpp>

#include "train/eval/descriptor_matchers.h"

namespace lmb {

struct FaissHnswOptions {
  int m = 32;                // graph degree (faiss's M; 2 M links on level 0)
  int ef_construction = 40;  // candidate list while building (faiss's default)
  int ef_search = 64;        // candidate list while searching; faiss searches with max(ef_search, k)
  void check() const;        // throws lmb::Error naming the field
};

class FaissHnswIndex : public KnnIndex {
 public:
  // Builds the graph over every observation. Throws lmb::Error on an empty set, descriptors whose
  // bits are not a multiple of 8, or invalid options.
  FaissHnswIndex(TrainingObservations observations, const FaissHnswOptions& options = {});
  ~FaissHnswIndex() override;

  // Approximate k nearest observations (Hamming distance), sorted by (distance, index).
  std::vector<std::vector<Neighbor>> search(const uint8_t* descriptors, int64_t num, int k) const override;
  const TrainingObservations& observations() const override { return obs_; }
  bool exact_hamming() const override { return false; }
  nlohmann::json parameters() const override;

 private:
  struct Impl;
  TrainingObservations obs_;
  FaissHnswOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lmb
