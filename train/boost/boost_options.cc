#include "train/boost/boost_options.h"

#include <cmath>

#include "common/error.h"

namespace lmb {

void TrainingSetOptions::check() const {
  LMB_CHECK(top_k_landmarks > 0, "training set: top_k_landmarks must be > 0, got " << top_k_landmarks);
  LMB_CHECK(min_train_observations >= 1,
            "training set: min_train_observations must be >= 1, got " << min_train_observations);
  LMB_CHECK(std::isfinite(validation_fraction) && validation_fraction >= 0.0 && validation_fraction < 1.0,
            "training set: validation_fraction must be in [0, 1), got " << validation_fraction);
  LMB_CHECK(background_cap >= 0, "training set: background_cap must be >= 0, got " << background_cap);
}

void BoostOptions::check() const {
  LMB_CHECK(std::isfinite(negative_weight_ratio) && negative_weight_ratio >= 0.0,
            "boost options: negative_weight_ratio must be finite and >= 0, got " << negative_weight_ratio);
  LMB_CHECK(background_negatives >= 0,
            "boost options: background_negatives must be >= 0 (0 = all), got " << background_negatives);
  LMB_CHECK(learning_rate > 0.0 && learning_rate <= 1.0,
            "boost options: learning_rate must be in (0, 1], got " << learning_rate);
  LMB_CHECK(num_rounds > 0, "boost options: num_rounds must be > 0, got " << num_rounds);
  LMB_CHECK(dims_per_round > 0, "boost options: dims_per_round must be > 0, got " << dims_per_round);
  LMB_CHECK(candidate_dims >= 0, "boost options: candidate_dims must be >= 0 (0 = all dims), got " << candidate_dims);
  LMB_CHECK(max_thresholds_per_dim >= 0 && max_thresholds_per_dim <= 255,
            "boost options: max_thresholds_per_dim must be in [0, 255], got " << max_thresholds_per_dim);
  LMB_CHECK(negatives_per_class >= 0,
            "boost options: negatives_per_class must be >= 0, got " << negatives_per_class);
  LMB_CHECK(max_negatives_per_class >= negatives_per_class,
            "boost options: max_negatives_per_class (" << max_negatives_per_class
                << ") must be >= negatives_per_class (" << negatives_per_class << ")");
  LMB_CHECK(mining_interval >= 0, "boost options: mining_interval must be >= 0, got " << mining_interval);
  LMB_CHECK(mining_pool_size >= 0, "boost options: mining_pool_size must be >= 0, got " << mining_pool_size);
  LMB_CHECK(mined_per_sample >= 1, "boost options: mined_per_sample must be >= 1, got " << mined_per_sample);
  LMB_CHECK(std::isfinite(exclusion_radius) && exclusion_radius >= 0.0,
            "boost options: exclusion_radius must be a finite distance >= 0 m, got " << exclusion_radius);
  LMB_CHECK(validation_interval >= 0,
            "boost options: validation_interval must be >= 0, got " << validation_interval);
  LMB_CHECK(max_validation_samples >= 0,
            "boost options: max_validation_samples must be >= 0, got " << max_validation_samples);
  LMB_CHECK(sharing_single_starts >= 0,
            "boost options: sharing_single_starts must be >= 0, got " << sharing_single_starts);
  LMB_CHECK(refine_top >= 0, "boost options: refine_top must be >= 0, got " << refine_top);
  LMB_CHECK(sharing_max_iterations >= 1,
            "boost options: sharing_max_iterations must be >= 1, got " << sharing_max_iterations);
}

void BoostOptions::check(int32_t num_dims) const {
  check();
  LMB_CHECK(num_dims > 0, "boost options: the features have no dimensions");
  LMB_CHECK(candidate_dims <= num_dims, "boost options: candidate_dims (" << candidate_dims
                                            << ") exceeds the feature dimension (" << num_dims << ")");
  LMB_CHECK(candidate_dims == 0 || dims_per_round <= candidate_dims,
            "boost options: dims_per_round (|F_m| = " << dims_per_round << ") exceeds candidate_dims ("
                                                      << candidate_dims << ")");
  LMB_CHECK(dims_per_round <= num_dims, "boost options: dims_per_round (|F_m| = "
                                            << dims_per_round << ") exceeds the feature dimension ("
                                            << num_dims << ")");
}

}  // namespace lmb
