#include "train/eval/faiss_index.h"

#include <omp.h>

#include <algorithm>
#include <utility>

#include <faiss/IndexBinaryHNSW.h>
#include <faiss/impl/FaissException.h>

#include "common/error.h"

namespace lmb {

void FaissHnswOptions::check() const {
  LMB_CHECK(m >= 2 && m <= 256, "FaissHnswOptions: m " << m << " must be in 2..256");
  LMB_CHECK(ef_construction >= 1, "FaissHnswOptions: ef_construction " << ef_construction << " must be >= 1");
  LMB_CHECK(ef_search >= 1, "FaissHnswOptions: ef_search " << ef_search << " must be >= 1");
}

struct FaissHnswIndex::Impl {
  explicit Impl(int bits, int m) : index(bits, m) {}
  faiss::IndexBinaryHNSW index;
};

FaissHnswIndex::FaissHnswIndex(TrainingObservations observations, const FaissHnswOptions& options)
    : obs_(std::move(observations)), options_(options) {
  options_.check();
  LMB_CHECK(obs_.descriptor_bytes > 0 && obs_.size() > 0, "FaissHnswIndex: no training observation");
  LMB_CHECK(static_cast<int64_t>(obs_.descriptors.size()) == obs_.size() * obs_.descriptor_bytes,
            "FaissHnswIndex: " << obs_.descriptors.size() << " descriptor bytes for " << obs_.size()
                               << " observations of " << obs_.descriptor_bytes << " bytes");
  omp_set_num_threads(1);
  try {
    impl_ = std::make_unique<Impl>(obs_.descriptor_bytes * 8, options_.m);
    impl_->index.hnsw.efConstruction = options_.ef_construction;
    impl_->index.hnsw.efSearch = options_.ef_search;
    impl_->index.add(obs_.size(), obs_.descriptors.data());
  } catch (const faiss::FaissException& e) {
    LMB_FAIL("FaissHnswIndex: faiss failed to build the index: " << e.what());
  }
}

FaissHnswIndex::~FaissHnswIndex() = default;

std::vector<std::vector<Neighbor>> FaissHnswIndex::search(const uint8_t* descriptors, int64_t num, int k) const {
  LMB_CHECK(k >= 1, "FaissHnswIndex::search: k " << k << " must be >= 1");
  std::vector<std::vector<Neighbor>> out(static_cast<size_t>(std::max<int64_t>(num, 0)));
  if (num <= 0) return out;
  const size_t kk = static_cast<size_t>(k);
  std::vector<int32_t> distances(static_cast<size_t>(num) * kk);
  std::vector<faiss::IndexBinary::idx_t> labels(static_cast<size_t>(num) * kk);
  omp_set_num_threads(1);
  try {
    impl_->index.search(num, descriptors, k, distances.data(), labels.data());
  } catch (const faiss::FaissException& e) {
    LMB_FAIL("FaissHnswIndex: faiss search failed: " << e.what());
  }
  for (size_t q = 0; q < out.size(); ++q) {
    for (size_t j = 0; j < kk; ++j) {
      const auto label = labels[q * kk + j];
      if (label < 0) continue;  // fewer than k found
      out[q].push_back(Neighbor{static_cast<int64_t>(label), static_cast<double>(distances[q * kk + j])});
    }
    std::sort(out[q].begin(), out[q].end(), [](const Neighbor& a, const Neighbor& b) {
      return a.distance < b.distance || (a.distance == b.distance && a.index < b.index);
    });
  }
  return out;
}

nlohmann::json FaissHnswIndex::parameters() const {
  return {{"index", "faiss IndexBinaryHNSW (approximate)"},
          {"faiss_version", std::to_string(FAISS_VERSION_MAJOR) + "." + std::to_string(FAISS_VERSION_MINOR) + "." +
                                std::to_string(FAISS_VERSION_PATCH)},
          {"hnsw_m", options_.m},
          {"ef_construction", options_.ef_construction},
          {"ef_search", options_.ef_search}};
}

}  // namespace lmb
