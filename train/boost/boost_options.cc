#include "train/boost/boost_options.h"

#include <utility>

#include "common/error.h"

namespace lmb {

const std::vector<Setting<TrainingSetOptions>>& training_set_settings() {
  using T = TrainingSetOptions;
  static const std::vector<Setting<T>> settings = {
      {"top_k_landmarks", [](T& o) -> SettingRef { return &o.top_k_landmarks; }, SettingRange::at_least(1),
       "classes: the K best landmarks by quality"},
      {"min_train_observations", [](T& o) -> SettingRef { return &o.min_train_observations; },
       SettingRange::at_least(1), "a selected landmark keeps at least this many training samples"},
      {"validation_fraction", [](T& o) -> SettingRef { return &o.validation_fraction; },
       SettingRange::half_open(0.0, 1.0), "fraction of a landmark's map observations held out for validation"},
      {"background_cap", [](T& o) -> SettingRef { return &o.background_cap; }, SettingRange::at_least(0),
       "at most this many background samples; 0 = none"},
      {"seed", [](T& o) -> SettingRef { return &o.seed; }, SettingRange::any(),
       "seed of the hold-out and background sampling"},
      {"calibration_frames", [](T& o) -> SettingRef { return &o.calibration_frames; }, SettingRange::at_least(0),
       "map frames held out of training whole for the pose calibration, at most; 0 = none"},
      {"calibration_frame_share", [](T& o) -> SettingRef { return &o.calibration_frame_share; },
       SettingRange::open_closed(0.0, 1.0), "... and at most this share of the map-session frames"},
      {"min_calibration_frames", [](T& o) -> SettingRef { return &o.min_calibration_frames; },
       SettingRange::at_least(1), "none held out when fewer than this would be"},
      {"calibration_folds", [](T& o) -> SettingRef { return &o.calibration_folds; }, SettingRange::at_least(0),
       "a map too small to hold calibration frames out is cross-fitted: this many folds of its frames (every K-th), "
       "one fold model each; 0 = never"},
      {"calibration_fold", [](T& o) -> SettingRef { return &o.calibration_fold; }, SettingRange::at_least(-1),
       "the fold this run holds out (a fold model), -1 = none (the full model)"},
  };
  return settings;
}

const std::vector<Setting<BoostOptions>>& boost_settings() {
  using T = BoostOptions;
  static const std::vector<Setting<T>> settings = {
      {"num_rounds", [](T& o) -> SettingRef { return &o.num_rounds; }, SettingRange::at_least(1),
       "M, shared stumps (rounds)"},
      {"dims_per_round", [](T& o) -> SettingRef { return &o.dims_per_round; }, SettingRange::at_least(1),
       "|F_m|, candidate dimensions drawn per round"},
      {"candidate_dims", [](T& o) -> SettingRef { return &o.candidate_dims; }, SettingRange::at_least(0),
       "F_m is drawn from dims [0, candidate_dims) only; 0 = all"},
      {"learning_rate", [](T& o) -> SettingRef { return &o.learning_rate; }, SettingRange::open_closed(0.0, 1.0),
       "shrinkage of every round's stump and constants"},
      {"seed", [](T& o) -> SettingRef { return &o.seed; }, SettingRange::any(),
       "seed of the F_m draw, negative sampling and pools"},
      {"max_thresholds_per_dim", [](T& o) -> SettingRef { return &o.screening.max_thresholds; },
       SettingRange::closed(0, 255), "candidate thresholds per dimension; 0 = all distinct bins"},
      {"refine_top", [](T& o) -> SettingRef { return &o.screening.refine_top; }, SettingRange::at_least(0),
       "screened candidates that get the full sharing-set search; 0 = full search on all"},
      {"screening_step", [](T& o) -> SettingRef { return &o.screening.step; }, SettingRange::any(),
       "screening adds one alternation step from each class group"},
      {"blocked_screening", [](T& o) -> SettingRef { return &o.screening.blocked; }, SettingRange::any(),
       "screen eight dims per class-major pass (false: one column pass per dim)"},
      {"sharing_single_starts", [](T& o) -> SettingRef { return &o.sharing.single_starts; }, SettingRange::at_least(0),
       "sharing-set search starts at the best single classes"},
      {"sharing_max_iterations", [](T& o) -> SettingRef { return &o.sharing.max_iterations; },
       SettingRange::at_least(1), "sharing-set search alternation steps per start"},
      {"negatives_per_class", [](T& o) -> SettingRef { return &o.negatives.per_class; }, SettingRange::at_least(0),
       "initial |L-_c|, bootstrapped through the visual words"},
      {"max_negatives_per_class", [](T& o) -> SettingRef { return &o.negatives.max_per_class; },
       SettingRange::at_least(0), "cap of |L-_c| after hard-negative mining"},
      {"exclusion_radius", [](T& o) -> SettingRef { return &o.negatives.exclusion_radius; },
       SettingRange::finite_at_least(0.0), "meters: never a negative of a class whose landmark is closer"},
      {"negative_weight_ratio", [](T& o) -> SettingRef { return &o.negatives.weight_ratio; },
       SettingRange::finite_at_least(0.0), "a class's negatives weigh this times its positives; 0 = 1 each"},
      {"background_negatives", [](T& o) -> SettingRef { return &o.negatives.background; }, SettingRange::at_least(0),
       "negatives of the background class; 0 = every landmark training sample"},
      {"mining_interval", [](T& o) -> SettingRef { return &o.mining.interval; }, SettingRange::at_least(0),
       "mine hard negatives every K rounds; 0 = never"},
      {"mining_pool_size", [](T& o) -> SettingRef { return &o.mining.pool_size; }, SettingRange::at_least(0),
       "training samples whose scores are tracked for mining"},
      {"mined_per_sample", [](T& o) -> SettingRef { return &o.mining.per_sample; }, SettingRange::at_least(1),
       "a pool sample joins the negatives of at most this many classes"},
      {"validation_interval", [](T& o) -> SettingRef { return &o.validation.interval; }, SettingRange::at_least(0),
       "validation precision@1 every N rounds; 0 = never"},
      {"max_validation_samples", [](T& o) -> SettingRef { return &o.validation.max_samples; },
       SettingRange::at_least(0), "held-out samples scored at most"},
  };
  return settings;
}

const std::vector<Setting<AugmentOptions>>& augment_settings() {
  using T = AugmentOptions;
  static const std::vector<Setting<T>> settings = {
      {"copies", [](T& o) -> SettingRef { return &o.copies; }, SettingRange::closed(0, 16),
       "augmented samples per training observation (0 = no augmentation)"},
      {"dropout", [](T& o) -> SettingRef { return &o.dropout; }, SettingRange::closed(-1.0, 0.95),
       "share of a frame's keypoints dropped in a copy; -1 = measured (1 - the detector's repeatability on the map)"},
      {"position_sigma", [](T& o) -> SettingRef { return &o.position_sigma; }, SettingRange::closed(-1.0, 10.0),
       "keypoint position noise, keypoint scales; -1 = measured (the map's reprojection residuals)"},
      {"scale_sigma", [](T& o) -> SettingRef { return &o.scale_sigma; }, SettingRange::closed(-1.0, 2.0),
       "keypoint log-scale noise; -1 = measured (spread of size x depth along the map's tracks)"},
      {"rotation_deg", [](T& o) -> SettingRef { return &o.rotation_deg; }, SettingRange::closed(0.0, 90.0),
       "gravity direction noise of a copy, degrees"},
      {"seed", [](T& o) -> SettingRef { return &o.seed; }, SettingRange::any(), "seed of the augmentation draws"},
  };
  return settings;
}

void AugmentOptions::check() const {
  check_settings("augment", augment_settings(), *this);
  for (const auto& [name, v] : {std::pair{"dropout", dropout}, std::pair{"position_sigma", position_sigma},
                                std::pair{"scale_sigma", scale_sigma}}) {
    LMB_CHECK(v == -1.0 || v >= 0.0, "augment: " << name << " must be -1 (measured) or >= 0, got " << v);
  }
}

void TrainingSetOptions::check() const {
  check_settings("training set", training_set_settings(), *this);
  LMB_CHECK(calibration_fold < calibration_folds, "training set: calibration_fold ("
                                                      << calibration_fold << ") must be -1 or below calibration_folds ("
                                                      << calibration_folds << ")");
}

void BoostOptions::check() const {
  check_settings("boost options", boost_settings(), *this);
  LMB_CHECK(negatives.max_per_class >= negatives.per_class,
            "boost options: max_negatives_per_class ("
                << negatives.max_per_class << ") must be >= negatives_per_class (" << negatives.per_class << ")");
}

void BoostOptions::check(int32_t num_dims) const {
  check();
  LMB_CHECK(num_dims > 0, "boost options: the features have no dimensions");
  LMB_CHECK(candidate_dims <= num_dims, "boost options: candidate_dims ("
                                            << candidate_dims << ") exceeds the feature dimension (" << num_dims
                                            << ")");
  LMB_CHECK(candidate_dims == 0 || dims_per_round <= candidate_dims,
            "boost options: dims_per_round (|F_m| = " << dims_per_round << ") exceeds candidate_dims ("
                                                      << candidate_dims << ")");
  LMB_CHECK(dims_per_round <= num_dims, "boost options: dims_per_round (|F_m| = " << dims_per_round
                                                                                  << ") exceeds the feature dimension ("
                                                                                  << num_dims << ")");
}

}  // namespace lmb
