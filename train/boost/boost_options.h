// Settings of the JointBoost learner and of the training set built from a landmark map. Every
// struct has defaults (the paper's configuration where the paper gives one). The learner's settings
// are grouped by the part that reads them; every setting is named once, in the schemas below
// (train/boost/settings.h), which the config file ([training_set], [boost] in
// train/boost/train_config.h), the checks and the command line's help share.
#pragma once

#include <cstdint>
#include <vector>

#include "common/types.h"
#include "train/boost/settings.h"
#include "train/boost/sharing_set.h"

namespace lmb {

// How the training set is cut out of a LandmarkMap (train/boost/training_set.h).
struct TrainingSetOptions {
  int32_t top_k_landmarks = 7500;      // classes: the K best landmarks by Landmark::quality
  int32_t min_train_observations = 2;  // a selected landmark keeps at least this many train samples
  // Held-out map observations for validation precision@1: per landmark with more than
  // min_train_observations map observations, this fraction (rounded down, at least 1) is held out.
  double validation_fraction = 0.1;
  int64_t background_cap = 40000;  // at most this many background samples (untracked keypoints
                                   // and observations of landmarks not selected); 0 = none
  uint64_t seed = 1;               // deterministic hold-out and background sampling
  // Map-session frames held out of training whole, so that the pose calibration (lboost export,
  // eval, calibrate, bundle) is fitted on frames the model never trained on, like a query's
  // (calibration_holdout_frames, train/boost/training_set.h): at most calibration_frames of them
  // and at most calibration_frame_share of the map-session frames; none when that is fewer than
  // min_calibration_frames (a small map keeps every frame for training, and its calibration falls
  // back to frames the model trained on). calibration_frames 0 = none (a run's config.toml without
  // the key: trained before it existed, read_run_train_config).
  int32_t calibration_frames = 50;
  double calibration_frame_share = 0.05;
  int32_t min_calibration_frames = 20;
  // Cross-fitting (docs/pose.md "Cross-fitted calibration"), for a map too small for the rule
  // above (it holds out none: fewer than min_calibration_frames / calibration_frame_share
  // map-session frames): the map-session frames (map order) are dealt into calibration_folds K
  // folds, every K-th frame each; fold model k (calibration_fold k in [0, K), trained by `lboost
  // train` after the model itself) holds out fold k whole, and the pose calibration is fitted on
  // every frame, each matched by the fold model that never saw it. The model itself
  // (calibration_fold -1) trains on every frame. 0 = no cross-fitting (a small map's calibration
  // falls back to frames the model trained on; a run's config.toml without the key).
  int32_t calibration_folds = 5;
  int32_t calibration_fold = -1;
  // Non-empty: the classes are exactly these landmarks (an area's, docs/areas.md; ascending,
  // distinct), top_k_landmarks is not used. Not a config key: set from TrainConfig::area.
  std::vector<landmark_t> class_landmarks;
  void check() const;  // throws lmb::Error naming the field
};

// Candidate thresholds and the screening that ranks (dim, threshold) candidates before the full
// sharing-set search (train/boost/feature_columns.h, train/boost/column_screener.h,
// train/boost/stump_search.h).
struct ScreeningOptions {
  // Candidate thresholds per dimension: the distinct bins of the column except its largest; when
  // there are more than this, the smallest bin (0 for sparse context dims) plus evenly spaced
  // quantiles of the remaining distinct bins (weighted by sample count). 0 = all distinct bins.
  int32_t max_thresholds = 8;
  // Every (dim, theta) of the round is ranked by the gains of its "rising" and "falling" class
  // groups (plus, with `step`, one alternation step from each); the refine_top best then get the
  // full sharing-set search. refine_top = 0: full search on every candidate (exact mode of the
  // tests). Measured on synthetic data (1,000 and 3,000 classes): refine_top 32 without the step
  // reaches 99.9% / 100% of the full search's gain.
  int32_t refine_top = 32;
  bool step = false;
  // Screening reads the entries class-major, eight dims (<= 15 thresholds each) per pass, instead
  // of one sample-major column pass per dim; the same gains bit for bit (column_screener_test),
  // ~4x faster at paper scale (jobs/bench_train.sh: "columns" against "blocked"). false: column passes only.
  bool blocked = true;
};

// The negative sets L-_c: bootstrapped at the start, grown by hard-negative mining
// (train/boost/negative_miner.h).
struct NegativeOptions {
  int32_t per_class = 40;          // initial |L-_c|, bootstrapped through the visual words
  int32_t max_per_class = 120;     // cap of |L-_c| after hard-negative mining
  double exclusion_radius = 0.05;  // meters: never a negative of c if its landmark is closer
  // Initial weights: a positive entry weighs 1 (or TrainingSet::sample_weight); the negatives of a
  // class share weight_ratio times its positives' total weight, so that each class's score
  // estimates a log-likelihood ratio on the same prior and classes rank fairly against each other
  // (with unit weights a class's constant drifts to log(|L+|/|L-|): the background class, with
  // thousands of positives, then outscores every landmark). 0 = every negative weighs 1.
  double weight_ratio = 1.0;
  // Negatives of the background class: this many landmark training samples (seeded); 0 = all.
  int32_t background = 0;
};

// Hard-negative mining from a pool of tracked training samples (train/boost/negative_miner.h).
struct MiningOptions {
  int32_t interval = 50;     // mine hard negatives every K rounds; 0 = never
  int32_t pool_size = 2048;  // train samples whose scores are tracked for mining
  int32_t per_sample = 1;    // a pool sample joins L-_c of at most this many classes ranked at or
                             // above its true class (best first)
};

// Validation precision@1 on held-out samples (train/boost/tracked_rows.h).
struct ValidationOptions {
  int32_t interval = 1;        // every N rounds; 0 = never
  int32_t max_samples = 4096;  // cap on held-out samples scored (deterministic subset)
};

struct BoostOptions {
  int32_t num_rounds = 2000;     // M, number of shared stumps
  int32_t dims_per_round = 500;  // |F_m|, candidate dimensions drawn per round
  // F_m is drawn from dims [0, candidate_dims) only; 0 = all dims. The layout puts the context
  // dims first (common/context_embedding.h), so num_regions * num_words trains on the visual
  // context alone, without descriptor bits (the paper's Table II).
  int32_t candidate_dims = 0;
  // Shrinkage: a, b and every k_c of a round are multiplied by this, in (0, 1]. Measured on a
  // 1,000-class rendered map (7.6 training observations a class, 300 rounds): validation P@1
  // 0.748 at 0.5 and 0.802 at 0.25 against 0.60 at 1 (Hamming nearest neighbour: 0.595); 100
  // initial negatives a class instead of 40 gave the same 0.803 at 0.25 with 60% more entries.
  // 0.125: at the jobs' round budgets its held-out P@1 beats 0.25's on `default`, `paper`
  // and TUM alike (docs/matching.md "Boosting shrinkage"); 0.0625 helped TUM and lost on `default`.
  double learning_rate = 0.125;
  uint64_t seed = 1;  // F_m draw, negative sampling, pools
  ScreeningOptions screening;
  // Sharing-set search (train/boost/sharing_set.h): starts of the alternating (alpha, beta) / set
  // refinement besides the "rising" and "falling" class groups, and alternation steps per start.
  SharingSearchOptions sharing;
  NegativeOptions negatives;
  MiningOptions mining;
  ValidationOptions validation;

  void check() const;  // throws lmb::Error naming the field
  // Checks against the data: candidate_dims <= num_dims, |F_m| <= the candidate dims.
  void check(int32_t num_dims) const;
};

// Context augmentation at training time (train/features/augmentation.h, docs/matching.md): each
// training observation gets up to `copies` extra samples whose context is computed from a perturbed
// copy of its frame: keypoints dropped as a detector fails to find them again, positions and scales
// jittered as a detector localizes them, the gravity direction rotated. Each rate left at -1 is
// measured on the map (augmentation.h: measure_map_noise). copies = 0: no augmentation, the run's
// config.toml has no [augment] table and the training set is the one of earlier versions.
struct AugmentOptions {
  int32_t copies = 0;     // augmented samples per training observation (at most; a copy whose
                          // own keypoint is dropped is not made)
  double dropout = -1.0;  // share of a frame's keypoints dropped; -1 = 1 - the detector's repeatability on the map
  double position_sigma = -1.0;  // position noise, keypoint scales (per axis); -1 = the map's reprojection residuals
  double scale_sigma = -1.0;     // log-scale noise; -1 = the spread of size x depth along the map's tracks
  double rotation_deg = 0.0;     // gravity direction noise (standard deviation, degrees)
  uint64_t seed = 1;             // the draws: a function of (seed, keypoint or frame, copy) only
  bool enabled() const { return copies > 0; }
  void check() const;  // throws lmb::Error naming the field
};

// The schemas: every setting with its config key, range and help.
const std::vector<Setting<TrainingSetOptions>>& training_set_settings();
const std::vector<Setting<BoostOptions>>& boost_settings();
const std::vector<Setting<AugmentOptions>>& augment_settings();

}  // namespace lmb
