#include "train/boost/training_set.h"

#include <algorithm>
#include <cstdio>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

// A map with `num_landmarks` landmarks (quality = id), landmark l observed in (l % 5) + 3 map
// frames, two untracked keypoints per frame, and one query frame observing every landmark.
// Appends a frame of session `session` observing `seen`, and two untracked keypoints.
void add_frame(LandmarkMap* map, bool query, int32_t session, const std::vector<landmark_t>& seen) {
  MapFrame f;
  f.is_query = query;
  f.session = session;
  f.first_keypoint = static_cast<int64_t>(map->keypoints.size());
  for (landmark_t l : seen) {
    map->keypoints.push_back({});
    map->keypoint_landmark.push_back(l);
    map->descriptors.push_back(0);
  }
  for (int i = 0; i < 2; ++i) {
    map->keypoints.push_back({});
    map->keypoint_landmark.push_back(kInvalidLandmarkId);
    map->descriptors.push_back(0);
  }
  f.num_keypoints = static_cast<int32_t>(map->keypoints.size() - f.first_keypoint);
  map->frames.push_back(f);
}

LandmarkMap make_map(int num_landmarks) {
  LandmarkMap map;
  map.descriptor_bytes = 1;
  map.cameras.resize(1);
  for (int l = 0; l < num_landmarks; ++l) {
    Landmark lm;
    lm.position = Eigen::Vector3d(l, 0, 0);
    lm.quality = static_cast<float>(l);
    map.landmarks.push_back(lm);
  }
  const auto add = [&](bool query, const std::vector<landmark_t>& seen) { add_frame(&map, query, 0, seen); };
  for (int f = 0; f < 8; ++f) {
    std::vector<landmark_t> seen;
    for (int l = 0; l < num_landmarks; ++l) {
      if (f < (l % 5) + 3) seen.push_back(l);
    }
    add(false, seen);
  }
  std::vector<landmark_t> all;
  for (int l = 0; l < num_landmarks; ++l) all.push_back(l);
  add(true, all);
  return map;
}

std::vector<int32_t> words_of(const LandmarkMap& map) {
  std::vector<int32_t> w(map.keypoints.size());
  for (size_t k = 0; k < w.size(); ++k) w[k] = static_cast<int32_t>(k % 16);
  return w;
}

TEST(TrainingSet, SelectsTopKHoldsOutAndSamplesBackground) {
  const LandmarkMap map = make_map(20);
  TrainingSetOptions o;
  o.top_k_landmarks = 6;
  o.validation_fraction = 0.25;
  o.background_cap = 10;
  const TrainingSet set = build_training_set(map, words_of(map), o);
  ASSERT_EQ(set.num_classes, 6);
  // The best six by quality are landmarks 14..19, in id order.
  for (int c = 0; c < 6; ++c) EXPECT_EQ(set.class_landmark[c], 14 + c);
  std::vector<int> train(7, 0), val(7, 0);
  for (int64_t s = 0; s < set.num_samples(); ++s) {
    const int64_t k = set.sample_keypoint[s];
    EXPECT_FALSE(map.frames[set.sample_frame[s]].is_query);
    EXPECT_EQ(set.sample_word[s], static_cast<int32_t>(k % 16));
    (set.sample_is_validation[s] ? val : train)[set.sample_class[s]]++;
    if (set.sample_class[s] < 6) {
      EXPECT_EQ(map.keypoint_landmark[k], set.class_landmark[set.sample_class[s]]);
    }
  }
  for (int c = 0; c < 6; ++c) {
    const int n = static_cast<int>((set.class_landmark[c] % 5) + 3);
    EXPECT_EQ(train[c] + val[c], n);
    EXPECT_EQ(val[c], std::max(1, static_cast<int>(0.25 * n)));
  }
  EXPECT_EQ(train[6], 10);  // background capped
  EXPECT_EQ(val[6], 0);
  // Deterministic.
  const TrainingSet again = build_training_set(map, words_of(map), o);
  EXPECT_EQ(again.sample_keypoint, set.sample_keypoint);
  EXPECT_EQ(again.sample_is_validation, set.sample_is_validation);
}

TEST(TrainingSet, GivenClassLandmarksAreExactlyTheClasses) {
  const LandmarkMap map = make_map(20);
  TrainingSetOptions o;
  o.top_k_landmarks = 3;  // not used with class_landmarks
  o.class_landmarks = {1, 4, 7, 8, 19};
  o.background_cap = 1000;
  const TrainingSet set = build_training_set(map, words_of(map), o);
  ASSERT_EQ(set.num_classes, 5);
  EXPECT_EQ(set.class_landmark, o.class_landmarks);
  int64_t background_of_landmarks = 0;
  for (int64_t s = 0; s < set.num_samples(); ++s) {
    const landmark_t l = map.keypoint_landmark[set.sample_keypoint[s]];
    if (set.sample_class[s] < 5) {
      EXPECT_EQ(l, o.class_landmarks[set.sample_class[s]]);
    } else if (l != kInvalidLandmarkId) {
      // Observations of landmarks outside the area are background, as unselected ones are.
      EXPECT_FALSE(std::binary_search(o.class_landmarks.begin(), o.class_landmarks.end(), l));
      ++background_of_landmarks;
    }
  }
  EXPECT_GT(background_of_landmarks, 0);
  // Bad lists: out of range, unsorted, too few observations.
  o.class_landmarks = {1, 20};
  EXPECT_THROW(build_training_set(map, words_of(map), o), Error);
  o.class_landmarks = {4, 1};
  EXPECT_THROW(build_training_set(map, words_of(map), o), Error);
  o.class_landmarks = {1, 2};
  o.min_train_observations = 5;  // landmark 1 has 4 map observations
  try {
    build_training_set(map, words_of(map), o);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("class landmark 1 has 4 map observations"), std::string::npos) << e.what();
  }
}

TEST(TrainingSet, UnselectedLandmarksBecomeBackground) {
  const LandmarkMap map = make_map(4);
  TrainingSetOptions o;
  o.top_k_landmarks = 2;
  o.background_cap = 1000000;
  const TrainingSet set = build_training_set(map, words_of(map), o);
  int64_t bg_tracked = 0;
  for (int64_t s = 0; s < set.num_samples(); ++s) {
    if (set.sample_class[s] == set.background_class() && map.keypoint_landmark[set.sample_keypoint[s]] >= 0) {
      ++bg_tracked;
      EXPECT_TRUE(set.sample_position[s].allFinite());
    }
  }
  EXPECT_EQ(bg_tracked, 3 + 4);  // landmarks 0 and 1 have 3 and 4 map observations
}

// A map of two map sessions (frames 0-4 and 5-9, every landmark seen in all ten) and a query
// session: every map session trains, and the held-out observations are drawn from both (no
// session is the validation set), about in proportion.
TEST(TrainingSet, EveryMapSessionTrainsAndValidates) {
  LandmarkMap map;
  map.descriptor_bytes = 1;
  map.cameras.resize(1);
  map.sessions = {{"map", SessionKind::kMap}, {"map-2", SessionKind::kMap}, {"query", SessionKind::kQuery}};
  const int num_landmarks = 300;
  for (int l = 0; l < num_landmarks; ++l) {
    Landmark lm;
    lm.quality = 1.f;
    map.landmarks.push_back(lm);
  }
  for (int f = 0; f < 11; ++f) {
    MapFrame frame;
    frame.session = f < 5 ? 0 : f < 10 ? 1 : 2;
    frame.is_query = f == 10;
    frame.first_keypoint = static_cast<int64_t>(map.keypoints.size());
    for (int l = 0; l < num_landmarks + 2; ++l) {
      map.keypoints.push_back({});
      map.keypoint_landmark.push_back(l < num_landmarks ? l : kInvalidLandmarkId);
      map.descriptors.push_back(0);
    }
    frame.num_keypoints = num_landmarks + 2;
    map.frames.push_back(frame);
  }
  TrainingSetOptions o;
  o.top_k_landmarks = num_landmarks;
  o.validation_fraction = 0.2;  // 2 of 10 observations a class
  const TrainingSet set = build_training_set(map, words_of(map), o);
  int train[3] = {0, 0, 0}, validation[3] = {0, 0, 0};
  for (int64_t s = 0; s < set.num_samples(); ++s) {
    if (set.sample_class[s] == set.background_class()) continue;
    const int32_t session = map.frames[set.sample_frame[s]].session;
    (set.sample_is_validation[s] ? validation : train)[session]++;
  }
  EXPECT_EQ(train[2] + validation[2], 0);  // the query session never
  EXPECT_EQ(train[0] + validation[0], 5 * num_landmarks);
  EXPECT_EQ(train[1] + validation[1], 5 * num_landmarks);
  EXPECT_EQ(validation[0] + validation[1], 2 * num_landmarks);
  std::printf("held-out observations by map session: %d, %d\n", validation[0], validation[1]);
  EXPECT_GT(validation[0], 0.4 * 2 * num_landmarks);
  EXPECT_GT(validation[1], 0.4 * 2 * num_landmarks);
}

// held_out_observations recomputes the training set's held-out observations from the map, the
// classes and the options (what `lboost eval --run` ranks), for several options.
TEST(TrainingSet, HeldOutObservationsAreTheValidationSamples) {
  const LandmarkMap map = make_map(40);
  for (const double fraction : {0.0, 0.1, 0.25, 0.5}) {
    for (const uint64_t seed : {1u, 7u}) {
      TrainingSetOptions o;
      o.top_k_landmarks = 25;
      o.validation_fraction = fraction;
      o.seed = seed;
      const TrainingSet set = build_training_set(map, words_of(map), o);
      std::vector<int64_t> validation;
      for (int64_t s = 0; s < set.num_samples(); ++s) {
        if (set.sample_is_validation[s]) validation.push_back(set.sample_keypoint[s]);
      }
      std::sort(validation.begin(), validation.end());
      EXPECT_EQ(held_out_observations(map, set.class_landmark, o), validation) << fraction << " " << seed;
      if (fraction > 0) {
        EXPECT_GE(validation.size(), 25u);  // at least one a class
      }
    }
  }
  EXPECT_THROW(held_out_observations(map, {40}, TrainingSetOptions()), Error);
}

// A map of one map session (40 frames) and a query frame between them (frame 20): landmark l
// (quality l) is observed in (l % 4) + 2 consecutive map frames from map frame l % 37, plus two
// untracked keypoints a frame.
LandmarkMap make_session_map() {
  LandmarkMap map;
  map.descriptor_bytes = 1;
  map.cameras.resize(1);
  map.sessions = {{"map", SessionKind::kMap}, {"query", SessionKind::kQuery}};
  const int num_landmarks = 60;
  for (int l = 0; l < num_landmarks; ++l) {
    Landmark lm;
    lm.quality = static_cast<float>(l);
    map.landmarks.push_back(lm);
  }
  int map_frame = 0;
  for (int f = 0; f < 41; ++f) {
    const bool query = f == 20;
    std::vector<landmark_t> seen;
    for (int l = 0; l < num_landmarks; ++l) {
      if (query || (map_frame >= l % 37 && map_frame < l % 37 + l % 4 + 2)) seen.push_back(l);
    }
    add_frame(&map, query, query ? 1 : 0, seen);
    if (!query) ++map_frame;
  }
  return map;
}

// The pose calibration's frames are held out of training whole: known frames (every s-th map
// frame, the query frame skipped), none of their keypoints a sample, a landmark left with too few
// observations outside them no class, an area's class that would starve keeping them, and the
// validation samples still what held_out_observations recomputes.
TEST(TrainingSet, CalibrationFramesAreHeldOutWhole) {
  const LandmarkMap map = make_session_map();
  TrainingSetOptions o;
  o.top_k_landmarks = 60;
  o.validation_fraction = 0.25;
  o.calibration_frames = 10;
  o.calibration_frame_share = 0.25;
  o.min_calibration_frames = 2;
  // 40 map frames, h = min(10, floor(0.25 * 40)) = 10, every 4th; frame 20 is the query.
  EXPECT_EQ(calibration_holdout_frames(map, o), (std::vector<frame_t>{0, 4, 8, 12, 16, 21, 25, 29, 33, 37}));
  TrainingSetOptions p = o;
  p.calibration_frame_share = 0.1;  // h = 4, every 10th
  EXPECT_EQ(calibration_holdout_frames(map, p), (std::vector<frame_t>{0, 10, 21, 31}));
  p.min_calibration_frames = 5;  // 4 < 5: none
  EXPECT_TRUE(calibration_holdout_frames(map, p).empty());
  p = o;
  p.calibration_frames = 0;
  EXPECT_TRUE(calibration_holdout_frames(map, p).empty());
  // The default options hold none out of a 40-frame map (5%: 2 frames, fewer than 20): it is
  // cross-fitted with 5 fold models instead; a map that holds frames out is not.
  EXPECT_TRUE(calibration_holdout_frames(map, TrainingSetOptions()).empty());
  EXPECT_EQ(cross_fitting_folds(map, TrainingSetOptions()), 5);
  EXPECT_EQ(cross_fitting_folds(map, o), 0);
  TrainingSetOptions never;
  never.calibration_folds = 0;
  EXPECT_EQ(cross_fitting_folds(map, never), 0);

  std::vector<char> held(map.frames.size(), 0);
  for (frame_t f : calibration_holdout_frames(map, o)) held[static_cast<size_t>(f)] = 1;
  // Brute force: a landmark's observations outside the held-out frames.
  std::vector<int> outside(map.landmarks.size(), 0);
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    if (map.frames[f].is_query || held[static_cast<size_t>(f)]) continue;
    for (int64_t k = map.frames[f].first_keypoint; k < map.frames[f].first_keypoint + map.frames[f].num_keypoints;
         ++k) {
      if (map.keypoint_landmark[k] != kInvalidLandmarkId) ++outside[static_cast<size_t>(map.keypoint_landmark[k])];
    }
  }
  const TrainingSet set = build_training_set(map, words_of(map), o);
  std::vector<landmark_t> expected_classes;
  for (landmark_t l = 0; l < 60; ++l) {
    if (outside[static_cast<size_t>(l)] >= o.min_train_observations) expected_classes.push_back(l);
  }
  EXPECT_EQ(set.class_landmark, expected_classes);
  // Landmark 0 (map frames 0 and 1) keeps one observation outside frame 0: no class; without the
  // hold-out it is one.
  ASSERT_FALSE(std::binary_search(set.class_landmark.begin(), set.class_landmark.end(), 0));
  p = o;
  p.calibration_frames = 0;
  const TrainingSet all = build_training_set(map, words_of(map), p);
  EXPECT_EQ(all.class_landmark.front(), 0);
  EXPECT_GT(all.num_samples(), set.num_samples());
  std::vector<int64_t> validation;
  for (int64_t s = 0; s < set.num_samples(); ++s) {
    EXPECT_FALSE(held[static_cast<size_t>(set.sample_frame[s])]) << "sample " << s;
    if (set.sample_is_validation[s]) validation.push_back(set.sample_keypoint[s]);
  }
  std::sort(validation.begin(), validation.end());
  EXPECT_EQ(held_out_observations(map, set.class_landmark, o), validation);

  // An area's classes: landmark 0 would keep one observation, so it trains on both; landmark 5
  // (map frames 5..7, none held out) is unchanged.
  TrainingSetOptions area = o;
  area.class_landmarks = {0, 5};
  const TrainingSet a = build_training_set(map, words_of(map), area);
  std::vector<int> of_class(3, 0);
  bool frame0 = false;
  validation.clear();
  for (int64_t s = 0; s < a.num_samples(); ++s) {
    ++of_class[static_cast<size_t>(a.sample_class[s])];
    if (a.sample_class[s] == 0 && a.sample_frame[s] == 0) frame0 = true;
    if (a.sample_class[s] == a.background_class()) {
      EXPECT_FALSE(held[static_cast<size_t>(a.sample_frame[s])]);
    }
    if (a.sample_is_validation[s]) validation.push_back(a.sample_keypoint[s]);
  }
  EXPECT_TRUE(frame0);
  EXPECT_EQ(of_class[0], 2);
  EXPECT_EQ(of_class[1], 3);
  std::sort(validation.begin(), validation.end());
  EXPECT_EQ(held_out_observations(map, a.class_landmark, area), validation);
}

TEST(TrainingSet, AugmentedCopiesFollowTheOriginalsAndNeverCopyValidation) {
  const LandmarkMap map = make_map(20);
  TrainingSetOptions o;
  o.top_k_landmarks = 10;
  o.validation_fraction = 0.3;
  const TrainingSet plain = build_training_set(map, words_of(map), o);
  TrainingSet set = plain;
  // Keypoints of even index are kept in copy 1, every keypoint in copy 2.
  add_augmented_copies(&set, 2, [](int64_t keypoint, int32_t copy) { return copy == 2 || keypoint % 2 == 0; });
  set.check();
  const int64_t n = plain.num_samples();
  ASSERT_EQ(static_cast<int64_t>(set.sample_copy.size()), set.num_samples());
  int64_t expected = n;
  int64_t at = n;
  for (int64_t s = 0; s < n; ++s) {
    EXPECT_EQ(set.sample_copy[s], 0);
    EXPECT_EQ(set.sample_keypoint[s], plain.sample_keypoint[s]);
    if (plain.sample_is_validation[s]) continue;
    for (int32_t c = 1; c <= 2; ++c) {
      if (c == 1 && plain.sample_keypoint[s] % 2 != 0) continue;
      ++expected;
      ASSERT_LT(at, set.num_samples());
      EXPECT_EQ(set.sample_copy[at], c);
      EXPECT_EQ(set.sample_keypoint[at], plain.sample_keypoint[s]);
      EXPECT_EQ(set.sample_class[at], plain.sample_class[s]);
      EXPECT_EQ(set.sample_frame[at], plain.sample_frame[s]);
      EXPECT_EQ(set.sample_is_validation[at], 0);
      ++at;
    }
  }
  EXPECT_EQ(set.num_samples(), expected);
  EXPECT_GT(expected, n + n / 2);
  EXPECT_THROW(add_augmented_copies(&set, 1, [](int64_t, int32_t) { return true; }), Error);
  TrainingSet bad = set;
  for (int64_t s = 0; s < n; ++s) {
    if (bad.sample_is_validation[s]) {
      bad.sample_copy[s] = 1;
      break;
    }
  }
  EXPECT_THROW(bad.check(), Error);
}

TEST(TrainingSet, RejectsBadInput) {
  const LandmarkMap map = make_map(4);
  EXPECT_THROW(build_training_set(map, std::vector<int32_t>(3, 0), TrainingSetOptions()), Error);
  TrainingSetOptions o;
  o.min_train_observations = 100;
  EXPECT_THROW(build_training_set(map, words_of(map), o), Error);
  // A set whose class has no training positives, and a NaN weight.
  TrainingSet set = build_training_set(map, words_of(map), TrainingSetOptions());
  TrainingSet no_pos = set;
  for (int64_t s = 0; s < no_pos.num_samples(); ++s) {
    if (no_pos.sample_class[s] == 0) no_pos.sample_is_validation[s] = 1;
  }
  EXPECT_THROW(no_pos.check(), Error);
  TrainingSet nan_weight = set;
  nan_weight.sample_weight.assign(static_cast<size_t>(set.num_samples()), 1.f);
  nan_weight.sample_weight[3] = std::nanf("");
  EXPECT_THROW(nan_weight.check(), Error);
}

// Cross-fitting: fold k of K holds out every K-th map-session frame from position k (the query
// frame skipped, map order), the folds cover every map frame once, none of a fold's frames gives a
// training sample of its fold model, and the model itself (fold -1) trains on all.
TEST(TrainingSet, CalibrationFoldsDealTheFramesRoundRobin) {
  const LandmarkMap map = make_session_map();  // 40 map frames, frame 20 the query
  std::vector<frame_t> covered;
  for (int32_t k = 0; k < 3; ++k) {
    const std::vector<frame_t> fold = calibration_fold_frames(map, 3, k);
    ASSERT_FALSE(fold.empty());
    covered.insert(covered.end(), fold.begin(), fold.end());
  }
  std::sort(covered.begin(), covered.end());
  EXPECT_EQ(covered, map.map_session_frames());
  // Positions 1, 4, ..., 19 are frames 1, ..., 19; position 22 is frame 23 (frame 20 the query).
  const std::vector<frame_t> fold1 = calibration_fold_frames(map, 3, 1);
  EXPECT_EQ(std::vector<frame_t>(fold1.begin(), fold1.begin() + 8),
            (std::vector<frame_t>{1, 4, 7, 10, 13, 16, 19, 23}));
  EXPECT_TRUE(calibration_fold_frames(map, 3, -1).empty());
  EXPECT_THROW(calibration_fold_frames(map, 3, 3), Error);
  EXPECT_THROW(calibration_fold_frames(map, 41, 0), Error);                   // fewer frames than folds
  EXPECT_EQ(calibration_fold_frames(map, 40, 39), std::vector<frame_t>{40});  // one frame a fold

  const std::vector<int32_t> words(map.keypoints.size(), 0);
  TrainingSetOptions o;
  o.top_k_landmarks = 60;
  o.calibration_folds = 2;
  for (int32_t k = 0; k < 2; ++k) {
    o.calibration_fold = k;
    const std::vector<frame_t> fold = calibration_fold_frames(map, 2, k);
    EXPECT_EQ(calibration_holdout_frames(map, o), fold);
    const TrainingSet set = build_training_set(map, words, o);
    for (frame_t f : set.sample_frame) {
      EXPECT_FALSE(std::binary_search(fold.begin(), fold.end(), f)) << "fold " << k << " trains on frame " << f;
    }
  }
  o.calibration_fold = -1;
  const TrainingSet all = build_training_set(map, words, o);
  const std::set<frame_t> frames(all.sample_frame.begin(), all.sample_frame.end());
  EXPECT_EQ(frames.size(), map.map_session_frames().size());
  o.calibration_fold = 2;
  EXPECT_THROW(o.check(), Error);
}

}  // namespace
}  // namespace lmb
