// Export: a trained BoostModel plus the map, vocabulary and context regions it was trained with
// -> the inference model (infer/model.h, file model.lbm).
//
// What it adds to the trainer's model: each class's landmark position (from the map), the
// vocabulary and regions (so that inference computes the same feature values), and the inverted
// file: word w lists the landmark classes with at least min_word_observations map-frame (never
// query-frame) observations whose descriptor quantizes to w. Constant-only stumps (empty sharing
// set, already folded into the biases) are dropped.
#pragma once

#include <cstdint>

#include "common/context_regions.h"
#include "common/landmark_map.h"
#include "common/vocabulary.h"
#include "infer/model.h"
#include "train/boost/boost_model.h"

namespace lmb {

struct ExportOptions {
  int32_t min_word_observations = 1;  // observations of (class, word) for an inverted-file entry
  // Throws lmb::Error naming the field.
  void check() const;
};

struct ExportStats {
  int32_t num_classes = 0;
  int32_t num_stumps = 0;             // non-constant stumps kept
  int32_t num_used_dims = 0;          // distinct dims the stumps read
  int64_t sharing_entries = 0;        // sum of sharing-set sizes
  int64_t inverted_file_entries = 0;  // sum of inverted-list lengths
  double mean_candidates = 0.0;       // candidate classes per map-frame keypoint (its word's list)
};

// Builds the inference model's data. Throws lmb::Error when the pieces do not fit together:
// boost.check() fails, the map's descriptor length differs from the vocabulary's, the model's
// feature dimension differs from regions x words + descriptor bits, or a class landmark id is not
// in the map.
ModelData export_model_data(const BoostModel& boost, const LandmarkMap& map, const Vocabulary& vocabulary,
                            const ContextRegions& regions, const ExportOptions& options = {},
                            ExportStats* stats = nullptr);

}  // namespace lmb
