#include "train/boost/training_set.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numeric>

#include "common/error.h"
#include "common/random.h"

namespace lmb {

namespace {
constexpr uint64_t kHoldoutTag = 0x484F4C44;     // "HOLD"
constexpr uint64_t kBackgroundTag = 0x424B4752;  // "BKGR"

// The observations of one class landmark (its map keypoints) held out for validation: per landmark
// with more than min_train_observations map observations, floor(validation_fraction * n) of them
// (at least 1, leaving min_train_observations), those with the smallest seeded hashes; sorted.
std::vector<int64_t> held_out_of_landmark(const std::vector<int64_t>& observations, const TrainingSetOptions& options) {
  const int64_t n = static_cast<int64_t>(observations.size());
  if (options.validation_fraction <= 0.0 || n <= options.min_train_observations) return {};
  int64_t h = std::max<int64_t>(1, static_cast<int64_t>(std::floor(options.validation_fraction * n)));
  h = std::min<int64_t>(h, n - options.min_train_observations);
  std::vector<std::pair<uint64_t, int64_t>> keyed;
  for (int64_t k : observations) {
    keyed.emplace_back(counter_hash(options.seed, kHoldoutTag, static_cast<uint64_t>(k)), k);
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<int64_t> held;
  for (int64_t i = 0; i < h; ++i) held.push_back(keyed[i].second);
  std::sort(held.begin(), held.end());
  return held;
}

// Per map frame, 1 when calibration_holdout_frames holds it out.
std::vector<char> holdout_flags(const LandmarkMap& map, const TrainingSetOptions& options) {
  std::vector<char> out(static_cast<size_t>(map.num_frames()), 0);
  for (frame_t f : calibration_holdout_frames(map, options)) out[static_cast<size_t>(f)] = 1;
  return out;
}

// The map (non-query) observations of every landmark, by landmark: those outside the held-out
// frames in `kept`, those in them in `held_frames` (each in keypoint order). Checks the frames'
// keypoint ranges and the keypoints' landmarks.
void map_observations(const LandmarkMap& map, const std::vector<char>& held_out,
                      std::vector<std::vector<int64_t>>* kept, std::vector<std::vector<int64_t>>* held_frames,
                      std::vector<int64_t>* untracked) {
  const int64_t num_keypoints = static_cast<int64_t>(map.keypoints.size());
  const int64_t num_landmarks = static_cast<int64_t>(map.landmarks.size());
  kept->assign(static_cast<size_t>(num_landmarks), {});
  held_frames->assign(static_cast<size_t>(num_landmarks), {});
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    const MapFrame& frame = map.frames[f];
    LMB_CHECK(frame.first_keypoint >= 0 && frame.num_keypoints >= 0 &&
                  frame.first_keypoint + frame.num_keypoints <= num_keypoints,
              "map: frame " << f << " (" << frame.name << ") keypoint range out of bounds");
    if (frame.is_query) continue;
    for (int64_t k = frame.first_keypoint; k < frame.first_keypoint + frame.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[k];
      LMB_CHECK(l == kInvalidLandmarkId || (l >= 0 && l < num_landmarks),
                "map: keypoint " << k << " refers to landmark " << l << " of " << num_landmarks);
      if (l == kInvalidLandmarkId) {
        if (untracked != nullptr && !held_out[static_cast<size_t>(f)]) untracked->push_back(k);
      } else {
        (held_out[static_cast<size_t>(f)] ? *held_frames : *kept)[static_cast<size_t>(l)].push_back(k);
      }
    }
  }
}

// An area's class that would keep fewer than min_train_observations observations outside the
// held-out frames trains on its observations in them too (sorted: keypoint order).
void keep_starved_classes(const std::vector<landmark_t>& classes, const TrainingSetOptions& options,
                          std::vector<std::vector<int64_t>>* kept, std::vector<std::vector<int64_t>>* held_frames) {
  if (options.class_landmarks.empty()) return;
  for (landmark_t l : classes) {
    auto& k = (*kept)[static_cast<size_t>(l)];
    auto& h = (*held_frames)[static_cast<size_t>(l)];
    if (static_cast<int64_t>(k.size()) >= options.min_train_observations || h.empty()) continue;
    k.insert(k.end(), h.begin(), h.end());
    std::sort(k.begin(), k.end());
    h.clear();
  }
}

// The class landmarks, ascending: options.class_landmarks (an area; each checked to exist and to
// have min_train_observations map observations), or the top_k_landmarks by quality (ties: smaller
// id) among those with at least min_train_observations.
std::vector<landmark_t> select_class_landmarks(const LandmarkMap& map,
                                               const std::vector<std::vector<int64_t>>& observations,
                                               const std::vector<std::vector<int64_t>>& held_frames,
                                               const TrainingSetOptions& options) {
  const int64_t num_landmarks = static_cast<int64_t>(map.landmarks.size());
  std::vector<landmark_t> candidates;
  if (!options.class_landmarks.empty()) {
    // The given classes (an area): each must exist and have enough observations to train on.
    for (size_t i = 0; i < options.class_landmarks.size(); ++i) {
      const landmark_t l = options.class_landmarks[i];
      LMB_CHECK(l >= 0 && l < num_landmarks,
                "training set: class landmark " << l << " is not a landmark of the map (" << num_landmarks << ")");
      LMB_CHECK(i == 0 || l > options.class_landmarks[i - 1],
                "training set: class landmarks must be ascending and distinct ("
                    << l << " after " << options.class_landmarks[i - 1] << ")");
      LMB_CHECK(static_cast<int64_t>(observations[l].size() + held_frames[l].size()) >= options.min_train_observations,
                "training set: class landmark "
                    << l << " has " << observations[l].size() + held_frames[l].size()
                    << " map observations, fewer than min_train_observations = " << options.min_train_observations);
    }
    candidates = options.class_landmarks;
  } else {
    for (landmark_t l = 0; l < num_landmarks; ++l) {
      if (static_cast<int64_t>(observations[l].size()) >= options.min_train_observations) {
        candidates.push_back(l);
      }
    }
    LMB_CHECK(!candidates.empty(),
              "training set: no landmark has at least " << options.min_train_observations << " map observations");
    std::sort(candidates.begin(), candidates.end(), [&](landmark_t a, landmark_t b) {
      if (map.landmarks[a].quality != map.landmarks[b].quality) {
        return map.landmarks[a].quality > map.landmarks[b].quality;
      }
      return a < b;
    });
    if (static_cast<int64_t>(candidates.size()) > options.top_k_landmarks) {
      candidates.resize(static_cast<size_t>(options.top_k_landmarks));
    }
    std::sort(candidates.begin(), candidates.end());
  }
  return candidates;
}

}  // namespace

std::vector<frame_t> calibration_holdout_frames(const LandmarkMap& map, const TrainingSetOptions& options) {
  options.check();
  if (options.calibration_fold >= 0)
    return calibration_fold_frames(map, options.calibration_folds, options.calibration_fold);
  const std::vector<frame_t> all = map.map_session_frames();
  const auto share =
      static_cast<int64_t>(std::floor(options.calibration_frame_share * static_cast<double>(all.size())));
  const int64_t h = std::min<int64_t>(options.calibration_frames, share);
  if (h <= 0 || h < options.min_calibration_frames) return {};
  const size_t step = (all.size() + static_cast<size_t>(h) - 1) / static_cast<size_t>(h);
  std::vector<frame_t> out;
  for (size_t i = 0; i < all.size(); i += step) out.push_back(all[i]);
  return out;
}

int32_t cross_fitting_folds(const LandmarkMap& map, const TrainingSetOptions& options) {
  TrainingSetOptions rule = options;
  rule.calibration_fold = -1;
  if (options.calibration_folds == 0 || !calibration_holdout_frames(map, rule).empty()) return 0;
  const auto frames = static_cast<int64_t>(map.map_session_frames().size());
  if (frames < 2) return 0;
  return static_cast<int32_t>(std::min<int64_t>(options.calibration_folds, frames));
}

std::vector<frame_t> calibration_fold_frames(const LandmarkMap& map, int32_t folds, int32_t fold) {
  LMB_CHECK(folds >= 1 && fold >= -1 && fold < folds,
            "calibration folds: fold " << fold << " of " << folds << " (want -1 <= fold < folds, folds >= 1)");
  if (fold < 0) return {};
  const std::vector<frame_t> all = map.map_session_frames();
  LMB_CHECK(static_cast<int64_t>(all.size()) >= static_cast<int64_t>(folds),
            "calibration folds: " << folds << " folds need at least " << folds << " map-session frames, the map has "
                                  << all.size());
  std::vector<frame_t> out;
  for (size_t i = static_cast<size_t>(fold); i < all.size(); i += static_cast<size_t>(folds)) out.push_back(all[i]);
  return out;
}

void TrainingSet::check() const {
  const int64_t n = num_samples();
  LMB_CHECK(num_classes >= 1, "training set: no landmark classes");
  LMB_CHECK(static_cast<int32_t>(class_landmark.size()) == num_classes &&
                static_cast<int32_t>(class_position.size()) == num_classes,
            "training set: class_landmark/class_position must have num_classes = " << num_classes << " entries");
  LMB_CHECK(static_cast<int64_t>(sample_word.size()) == n && static_cast<int64_t>(sample_position.size()) == n &&
                static_cast<int64_t>(sample_frame.size()) == n && static_cast<int64_t>(sample_keypoint.size()) == n &&
                static_cast<int64_t>(sample_is_validation.size()) == n,
            "training set: per-sample arrays must all have " << n << " entries");
  LMB_CHECK(sample_weight.empty() || static_cast<int64_t>(sample_weight.size()) == n,
            "training set: sample_weight must be empty or have " << n << " entries");
  for (size_t i = 0; i < sample_weight.size(); ++i) {
    LMB_CHECK(std::isfinite(sample_weight[i]) && sample_weight[i] > 0.f,
              "training set: sample " << i << " has weight " << sample_weight[i] << " (must be finite and > 0)");
  }
  LMB_CHECK(sample_copy.empty() || static_cast<int64_t>(sample_copy.size()) == n,
            "training set: sample_copy must be empty or have " << n << " entries");
  for (size_t i = 0; i < sample_copy.size(); ++i) {
    LMB_CHECK(sample_copy[i] >= 0 && (sample_copy[i] == 0 || !sample_is_validation[i]),
              "training set: sample " << i << " has copy " << sample_copy[i]
                                      << " (must be >= 0, and 0 for a validation sample)");
  }
  std::vector<int64_t> train_count(static_cast<size_t>(num_classes) + 1, 0);
  for (int64_t i = 0; i < n; ++i) {
    const int32_t c = sample_class[i];
    LMB_CHECK(c >= 0 && c <= num_classes,
              "training set: sample " << i << " has class " << c << " outside [0, " << num_classes << "]");
    if (!sample_is_validation[i]) ++train_count[c];
  }
  for (int32_t c = 0; c < num_classes; ++c) {
    LMB_CHECK(train_count[c] > 0,
              "training set: class " << c << " (landmark " << class_landmark[c] << ") has no training positives");
  }
  LMB_CHECK(train_count[num_classes] > 0,
            "training set: no background training samples (the map has no untracked keypoints and "
            "every landmark was selected; lower top_k_landmarks or raise background_cap)");
}

void add_augmented_copies(TrainingSet* set, int32_t copies, const std::function<bool(int64_t, int32_t)>& kept) {
  LMB_CHECK(copies >= 0, "augment: copies = " << copies << " must be >= 0");
  LMB_CHECK(set->sample_copy.empty(), "augment: the training set already has augmented copies");
  const int64_t n = set->num_samples();
  set->sample_copy.assign(static_cast<size_t>(n), 0);
  for (int64_t s = 0; s < n; ++s) {
    if (set->sample_is_validation[s]) continue;
    for (int32_t c = 1; c <= copies; ++c) {
      if (!kept(set->sample_keypoint[s], c)) continue;
      set->sample_class.push_back(set->sample_class[s]);
      set->sample_word.push_back(set->sample_word[s]);
      set->sample_position.push_back(set->sample_position[s]);
      set->sample_frame.push_back(set->sample_frame[s]);
      set->sample_keypoint.push_back(set->sample_keypoint[s]);
      set->sample_is_validation.push_back(0);
      if (!set->sample_weight.empty()) set->sample_weight.push_back(set->sample_weight[s]);
      set->sample_copy.push_back(c);
    }
  }
}

TrainingSet build_training_set(const LandmarkMap& map, const std::vector<int32_t>& keypoint_words,
                               const TrainingSetOptions& options) {
  options.check();
  const int64_t num_keypoints = static_cast<int64_t>(map.keypoints.size());
  LMB_CHECK(
      static_cast<int64_t>(keypoint_words.size()) == num_keypoints,
      "training set: " << keypoint_words.size() << " visual words given for " << num_keypoints << " map keypoints");
  LMB_CHECK(static_cast<int64_t>(map.keypoint_landmark.size()) == num_keypoints,
            "map: keypoint_landmark has " << map.keypoint_landmark.size() << " entries for " << num_keypoints
                                          << " keypoints");
  const int64_t num_landmarks = static_cast<int64_t>(map.landmarks.size());

  // Map (non-query) observations per landmark, outside the calibration frames and in them.
  const std::vector<char> held_out = holdout_flags(map, options);
  std::vector<std::vector<int64_t>> observations, in_held_frames;
  std::vector<int64_t> background;
  map_observations(map, held_out, &observations, &in_held_frames, &background);
  std::vector<frame_t> keypoint_frame(static_cast<size_t>(num_keypoints), kInvalidFrameId);
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    const MapFrame& frame = map.frames[f];
    if (frame.is_query) continue;
    for (int64_t k = frame.first_keypoint; k < frame.first_keypoint + frame.num_keypoints; ++k) keypoint_frame[k] = f;
  }

  // Qualification and top-K by quality, or the given classes.
  const std::vector<landmark_t> candidates = select_class_landmarks(map, observations, in_held_frames, options);
  keep_starved_classes(candidates, options, &observations, &in_held_frames);

  TrainingSet set;
  set.num_classes = static_cast<int32_t>(candidates.size());
  std::vector<int32_t> landmark_class(static_cast<size_t>(num_landmarks), -1);
  for (int32_t c = 0; c < set.num_classes; ++c) {
    landmark_class[candidates[c]] = c;
    set.class_landmark.push_back(candidates[c]);
    set.class_position.push_back(map.landmarks[candidates[c]].position);
  }
  // Observations of unselected landmarks are background too.
  for (landmark_t l = 0; l < num_landmarks; ++l) {
    if (landmark_class[l] < 0) background.insert(background.end(), observations[l].begin(), observations[l].end());
  }
  std::sort(background.begin(), background.end());
  if (static_cast<int64_t>(background.size()) > options.background_cap) {
    std::vector<std::pair<uint64_t, int64_t>> keyed;
    keyed.reserve(background.size());
    for (int64_t k : background)
      keyed.emplace_back(counter_hash(options.seed, kBackgroundTag, static_cast<uint64_t>(k)), k);
    std::nth_element(keyed.begin(), keyed.begin() + options.background_cap, keyed.end());
    keyed.resize(static_cast<size_t>(options.background_cap));
    background.clear();
    for (const auto& [h, k] : keyed) background.push_back(k);
    std::sort(background.begin(), background.end());
  }

  const float nan = std::numeric_limits<float>::quiet_NaN();
  auto add_sample = [&](int64_t k, int32_t c, bool validation) {
    set.sample_class.push_back(c);
    set.sample_word.push_back(keypoint_words[k]);
    const landmark_t l = map.keypoint_landmark[k];
    set.sample_position.push_back(l == kInvalidLandmarkId ? Eigen::Vector3f(nan, nan, nan)
                                                          : map.landmarks[l].position.cast<float>());
    set.sample_frame.push_back(keypoint_frame[k]);
    set.sample_keypoint.push_back(k);
    set.sample_is_validation.push_back(validation ? 1 : 0);
  };
  for (int32_t c = 0; c < set.num_classes; ++c) {
    const auto& obs = observations[candidates[c]];
    const std::vector<int64_t> held_keys = held_out_of_landmark(obs, options);
    for (size_t i = 0; i < obs.size(); ++i) {
      const bool v = std::find(held_keys.begin(), held_keys.end(), obs[i]) != held_keys.end();
      add_sample(obs[i], c, v);
    }
  }
  for (int64_t k : background) add_sample(k, set.num_classes, false);

  // Samples in keypoint order: the feature builder then reads frames sequentially.
  std::vector<int64_t> order(set.sample_class.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](int64_t a, int64_t b) { return set.sample_keypoint[a] < set.sample_keypoint[b]; });
  auto permute = [&](auto& v) {
    auto copy = v;
    for (size_t i = 0; i < order.size(); ++i) v[i] = copy[order[i]];
  };
  permute(set.sample_class);
  permute(set.sample_word);
  permute(set.sample_position);
  permute(set.sample_frame);
  permute(set.sample_keypoint);
  permute(set.sample_is_validation);
  set.check();
  return set;
}

std::vector<int64_t> held_out_observations(const LandmarkMap& map, const std::vector<landmark_t>& class_landmarks,
                                           const TrainingSetOptions& options) {
  options.check();
  const int64_t num_keypoints = static_cast<int64_t>(map.keypoints.size());
  const int64_t num_landmarks = static_cast<int64_t>(map.landmarks.size());
  LMB_CHECK(static_cast<int64_t>(map.keypoint_landmark.size()) == num_keypoints,
            "map: keypoint_landmark has " << map.keypoint_landmark.size() << " entries for " << num_keypoints
                                          << " keypoints");
  for (landmark_t l : class_landmarks) {
    LMB_CHECK(l >= 0 && l < num_landmarks,
              "held-out observations: class landmark " << l << " out of range [0, " << num_landmarks << ")");
  }
  std::vector<std::vector<int64_t>> all, in_held_frames;
  map_observations(map, holdout_flags(map, options), &all, &in_held_frames, nullptr);
  keep_starved_classes(class_landmarks, options, &all, &in_held_frames);
  std::vector<std::vector<int64_t>> observations(static_cast<size_t>(num_landmarks));
  for (landmark_t l : class_landmarks) observations[static_cast<size_t>(l)] = std::move(all[static_cast<size_t>(l)]);
  std::vector<int64_t> held;
  for (const std::vector<int64_t>& obs : observations) {
    const std::vector<int64_t> h = held_out_of_landmark(obs, options);
    held.insert(held.end(), h.begin(), h.end());
  }
  std::sort(held.begin(), held.end());
  return held;
}

}  // namespace lmb
