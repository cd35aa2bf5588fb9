// The samples the learner trains on: one per map keypoint observation kept for training, labelled
// with its class. Classes 0..C-1 are the selected landmarks; class C is the background (untracked
// keypoints and observations of landmarks that were not selected). Row i of the FeatureMatrix is
// sample i.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "common/landmark_map.h"
#include "common/types.h"
#include "train/boost/boost_options.h"

namespace lmb {

struct TrainingSet {
  int32_t num_classes = 0;                      // C landmark classes; the background class is C
  std::vector<landmark_t> class_landmark;       // size C: the map landmark of each class
  std::vector<Eigen::Vector3d> class_position;  // size C: world frame, meters

  // Per sample (all of size num_samples()):
  std::vector<int32_t> sample_class;             // 0..C (C = background)
  std::vector<int32_t> sample_word;              // visual word of the keypoint descriptor, -1 = none
  std::vector<Eigen::Vector3f> sample_position;  // its landmark's position (world, meters), NaN
                                                 // for untracked keypoints
  std::vector<frame_t> sample_frame;             // map frame
  std::vector<int64_t> sample_keypoint;          // index into LandmarkMap::keypoints, -1 if synthetic
  std::vector<uint8_t> sample_is_validation;     // 1 = held-out map observation (never trained on)
  // Optional initial weight of every entry of a sample (finite, > 0); empty = all 1.
  std::vector<float> sample_weight;
  // Optional augmentation copy of every sample: 0 = the observation itself, c > 0 = its c-th
  // augmented copy (context from a perturbed frame, train/features/augmentation.h; never a
  // validation sample). Empty = all 0.
  std::vector<int32_t> sample_copy;

  int32_t background_class() const { return num_classes; }
  int32_t num_classes_with_background() const { return num_classes + 1; }
  int64_t num_samples() const { return static_cast<int64_t>(sample_class.size()); }
  // Throws lmb::Error on inconsistent sizes, class indices out of range, a landmark class without
  // a training sample, no background training sample, or a non-finite / non-positive weight.
  void check() const;
};

// The map-session frames held out of training whole for the pose calibration: of the F frames of
// the map sessions (map order, as calibration_frames of train/eval/pose_calibration_fit.h), h =
// min(calibration_frames, floor(calibration_frame_share * F)) frames, every ceil(F / h)-th from the
// first; none when h < min_calibration_frames. Ascending. A function of the map and the options.
// A fold model (calibration_fold >= 0): calibration_fold_frames of its fold instead.
std::vector<frame_t> calibration_holdout_frames(const LandmarkMap& map, const TrainingSetOptions& options);

// The fold models a model trained with `options` on `map` is cross-fitted with: calibration_folds
// (at most one a map-session frame) when the rule of calibration_holdout_frames holds no frame out
// and the map has at least 2 map-session frames, else 0 (the model's calibration frames are its
// held-out ones, or none).
int32_t cross_fitting_folds(const LandmarkMap& map, const TrainingSetOptions& options);

// Fold `fold` of `folds` of the map-session frames (map order: fold k holds positions k, k + K,
// k + 2K, ... of the n frames, so each frame's neighbours train its fold model, as the held-out
// frames of a large map have trained neighbours), ascending; empty for fold -1. Throws lmb::Error
// for a fold out of range or a map with fewer frames than folds.
std::vector<frame_t> calibration_fold_frames(const LandmarkMap& map, int32_t folds, int32_t fold);

// Builds the training set from the map's non-query frames outside calibration_holdout_frames (their
// keypoints are no sample at all, except an area's class observations, below):
//  - classes: options.class_landmarks when given (each needs min_train_observations map
//    observations; a class that would keep fewer outside the held-out frames keeps its observations
//    in them too), else the top_k_landmarks landmarks by quality (ties: smaller id) among those
//    with at least min_train_observations map observations outside the held-out frames; ordered by
//    landmark id;
//  - validation: per class, floor(validation_fraction * n) observations (at least 1 when
//    validation_fraction > 0 and n > min_train_observations), chosen by a seeded hash;
//  - background: untracked keypoints and observations of unselected landmarks, at most
//    background_cap of them (seeded hash), all training samples.
// keypoint_words: per map keypoint its visual word (-1 = none), size map.keypoints.size().
// Throws lmb::Error on a malformed map, wrong word count, or no landmark qualifying.
TrainingSet build_training_set(const LandmarkMap& map, const std::vector<int32_t>& keypoint_words,
                               const TrainingSetOptions& options);

// Appends the augmented copies of every training (non-validation) sample of copy 0: for c in
// 1..copies, in sample order then copy order, a sample equal to it with sample_copy c, when
// kept(keypoint, c). The originals keep their indices, so the first num_samples() rows are the set
// without augmentation. Throws lmb::Error when copies < 0 or the set already has copies.
void add_augmented_copies(TrainingSet* set, int32_t copies, const std::function<bool(int64_t, int32_t)>& kept);

// The held-out map observations of a training set, from the map, its classes' landmarks and the
// options alone: the keypoints build_training_set marks sample_is_validation when its classes are
// `class_landmarks` (e.g. a trained model's), sorted (never a keypoint of a calibration frame). `lboost eval` ranks
// them: observations of the training sessions that the model never trained on. Throws lmb::Error on a malformed map or
// a landmark out of range.
std::vector<int64_t> held_out_observations(const LandmarkMap& map, const std::vector<landmark_t>& class_landmarks,
                                           const TrainingSetOptions& options);

}  // namespace lmb
