// Synthetic training problems of the learner's shape, for tests and benchmarks: context dims
// (sparse uint8 bins, mostly zero) followed by descriptor-bit dims (0/1).
//
// Classes come in alias groups that share one descriptor prototype (each observation flips bits
// with a small probability), so descriptors alone cannot tell the classes of a group apart. Each
// class has its own context signature (a few context dims with large values, each present with
// probability signature_keep); every sample also gets small noise values in a random
// noise_density fraction of the context dims. Background samples carry aliased or random
// descriptors and context noise only. Words: the prototype's word (a random word w.p. 0.1).
#pragma once

#include <cstdint>

#include "train/boost/training_set.h"
#include "train/features/feature_matrix.h"

namespace lmb {

struct SyntheticBoostOptions {
  int32_t num_classes = 40;
  int32_t observations_per_class = 12;  // including the held-out ones
  int32_t validation_per_class = 2;
  int64_t num_background = 200;
  int32_t context_dims = 256;
  int32_t descriptor_bits = 64;
  int32_t alias_group_size = 4;  // classes per descriptor prototype
  double descriptor_flip = 0.05;
  int32_t signature_dims = 12;
  double signature_keep = 0.8;
  double noise_density = 0.05;
  int32_t num_words = 16;
  uint64_t seed = 7;
  void check() const;
};

struct SyntheticBoostProblem {
  TrainingSet set;
  FeatureMatrix features;  // context dims first, then descriptor bits
  int32_t context_dims = 0;
  int32_t descriptor_bits = 0;
};

SyntheticBoostProblem make_synthetic_boost_problem(const SyntheticBoostOptions& options);

// The paper's shape: 7,500 classes x 15 observations (2 held out) + 37,500 background samples
// (150k samples), 16,384 context dims (15% non-zero) + 512 descriptor bits.
SyntheticBoostOptions paper_shape_synthetic_options();

}  // namespace lmb
