// What a checkpoint holds of the learner (train/checkpoint/checkpoint_h5.h): everything that
// changes during training. Restoring it into a learner built on the same features, training set
// and options continues the run bit for bit. The negative sets L-_c are the entries with z = -1;
// per-round scratch (fixed-point weights, class totals, histograms) is recomputed from these at
// the start of every round.
#pragma once

#include <cstdint>
#include <vector>

#include "train/boost/boost_model.h"

namespace lmb {

struct LearnerState {
  BoostModel model;                   // stumps so far (rounds done = stumps.size()) and biases
  std::vector<int64_t> entry_sample;  // entries, sample-major, (sample, code) ascending
  std::vector<int32_t> entry_code;    // class * 2 + (z < 0)
  std::vector<double> entry_weight;   // stored weights; true = stored * 2^weight_exponent
  int32_t weight_exponent = 0;
  std::vector<int64_t> tracked_samples;  // validation rows first, then the mining pool
  int64_t num_validation_rows = 0;
  std::vector<float> tracked_scores;  // tracked_samples.size() x (C + 1), row-major (all parts')
  std::vector<double> class_offset;   // C + 1: sum of k_c over the rounds
  std::vector<double> negative_unit;  // C + 1: initial weight of a negative of each class
  double last_validation = -1.0;
};

}  // namespace lmb
