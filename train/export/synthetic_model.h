// A random but structurally realistic inference model, for timing inference at the paper's scale
// without training one (`lboost-bench infer --synthetic-paper`).
//
// Shape (defaults = the paper's configuration): C landmark classes, R regions x W words of context
// plus 8 * descriptor_bytes descriptor bits, M stumps of which a share reads context dims (the
// paper: 985 of 2,000) and the rest descriptor bits (threshold 0). Sharing-set sizes follow the
// paper's Fig. "sharing set size": about half the classes in the first rounds, shrinking as
// training goes on:
//   |S_m| = clamp(round(C / 2 * (1 + m / sharing_m0)^-sharing_decay * exp(N(0, 0.5^2))), 1, C)
// (defaults: 3,750 at m = 0, ~250 at m = 500, ~90 at m = 2,000, mean ~290 classes a stump); the
// background joins a stump's set with probability background_share. The inverted file gives
// each class one word plus each further word with probability extra_word_probability (the
// observations of a landmark quantize to a few words). Values (a, b, biases, thresholds,
// positions) are random. The same options and seed give the same model.
#pragma once

#include <cstdint>

#include "infer/model.h"

namespace lmb {

struct SyntheticModelOptions {
  int32_t num_classes = 7500;
  int32_t num_stumps = 2000;
  int32_t num_regions = 1000;
  int32_t num_words = 16;
  int32_t descriptor_bytes = 64;
  double context_stump_share = 985.0 / 2000.0;
  double sharing_m0 = 20.0;
  double sharing_decay = 0.8;
  double background_share = 0.3;
  double extra_word_probability = 0.1;
  uint64_t seed = 1;

  // Throws lmb::Error naming the field.
  void check() const;
};

struct SyntheticModelStats {
  int64_t sharing_entries = 0;        // sum of sharing-set sizes
  int64_t inverted_file_entries = 0;  // sum of inverted-list lengths
};

// Builds the model data (passes ModelData::check). Throws lmb::Error for invalid options.
ModelData make_synthetic_model(const SyntheticModelOptions& options, SyntheticModelStats* stats = nullptr);

}  // namespace lmb
