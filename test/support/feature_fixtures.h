// Small fixtures for the tests of the training features (train/features): a random binary
// vocabulary and a small set of context regions. Deterministic for a seed.
#pragma once

#include <cstdint>
#include <vector>

#include "common/context_regions.h"
#include "common/random.h"
#include "common/vocabulary.h"

namespace lmb::test {

// `words` random words of `bytes` bytes each.
inline Vocabulary random_vocabulary(int words, int bytes, uint64_t seed) {
  Rng rng(seed);
  std::vector<uint8_t> w(static_cast<size_t>(words) * bytes);
  for (auto& b : w) b = static_cast<uint8_t>(rng.below(256));
  return Vocabulary(bytes, w);
}

// 60 regions (seed 4): enough to cover every region shape, few enough for brute-force references.
inline ContextRegions small_regions() {
  ContextRegionOptions o;
  o.num_regions = 60;
  o.seed = 4;
  return ContextRegions(o);
}

}  // namespace lmb::test
