// The settings of `lboost train`: TOML config file <-> structs. The effective config (defaults,
// file, then flags) is written into the run directory as config.toml; the same text is what a
// checkpoint can hash to refuse a changed config.
//
//   [training_set]  top_k_landmarks, min_train_observations, validation_fraction, background_cap, seed
//   [boost]         num_rounds, dims_per_round, candidate_dims, max_thresholds_per_dim, negatives_per_class,
//                   max_negatives_per_class, mining_interval, mining_pool_size, mined_per_sample,
//                   exclusion_radius, validation_interval, max_validation_samples,
//                   sharing_single_starts, sharing_max_iterations, refine_top, screening_step, seed
//   [regions]       num_regions, seed, min_area, max_area, max_aspect, max_offset
//   [features]      threads
//   [checkpoint]    interval, keep (train/checkpoint/checkpoint_h5.h; not compared on resume)
#pragma once

#include <filesystem>
#include <string>

#include "common/context_regions.h"
#include "train/boost/boost_options.h"

namespace lmb {

struct TrainConfig {
  TrainingSetOptions training_set;
  BoostOptions boost;
  ContextRegionOptions regions;
  int feature_threads = 1;
  int32_t checkpoint_interval = 100;  // rounds between checkpoints (0 = only on a signal and at the end)
  int32_t checkpoint_keep = 3;        // newest checkpoints kept
  void check() const;  // every part's check(); throws lmb::Error naming the field
};

// Overrides the fields present in a TOML document. Throws lmb::Error naming `what`, the table and
// key on a parse error, an unknown table or key, or a value of the wrong type or range.
void apply_train_config_toml(const std::string& toml_text, const std::string& what, TrainConfig* config);
TrainConfig read_train_config(const std::filesystem::path& path);
// Every field, as TOML (round-trips through apply_train_config_toml).
std::string train_config_toml(const TrainConfig& config);

}  // namespace lmb
