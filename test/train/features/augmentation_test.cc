#include "train/features/augmentation.h"

#include <algorithm>
#include <cmath>
#include <set>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/hamming.h"
#include "common/random.h"
#include "test/support/feature_fixtures.h"
#include "train/features/build_features.h"

namespace lmb {
namespace {

using test::random_vocabulary;
using test::small_regions;

constexpr int kBytes = 16;

// Frames of random keypoints (pinhole camera, tilted gravity).
LandmarkMap random_map(uint64_t seed, int frames = 5, int keypoints = 250) {
  Rng rng(seed);
  LandmarkMap map;
  map.descriptor_bytes = kBytes;
  Camera pinhole;
  pinhole.width = 640;
  pinhole.height = 480;
  pinhole.params = {500, 510, 320, 240};
  map.cameras = {pinhole};
  map.sessions = {MapSession{"map", SessionKind::kMap}};
  for (int f = 0; f < frames; ++f) {
    MapFrame frame;
    frame.name = "map/" + std::to_string(f) + ".png";
    const double roll = rng.uniform(-1.0, 1.0);
    frame.gravity_in_cam = Eigen::Vector3d(std::sin(roll), std::cos(roll), 0.3).normalized();
    frame.first_keypoint = static_cast<int64_t>(map.keypoints.size());
    frame.num_keypoints = keypoints;
    map.frames.push_back(frame);
    for (int k = 0; k < keypoints; ++k) {
      map.keypoints.push_back(Keypoint{static_cast<float>(rng.uniform(0, 639)), static_cast<float>(rng.uniform(0, 479)),
                                       static_cast<float>(rng.uniform(8, 40)), -1.f});
      map.keypoint_landmark.push_back(kInvalidLandmarkId);
    }
  }
  map.descriptors.resize(map.keypoints.size() * kBytes);
  for (auto& b : map.descriptors) b = static_cast<uint8_t>(rng.below(256));
  return map;
}

AugmentNoise some_noise() {
  AugmentNoise n;
  n.dropout = 0.3;
  n.position_sigma = 0.2;
  n.scale_sigma = 0.15;
  n.rotation_rad = 0.05;
  n.seed = 11;
  return n;
}

TEST(Augmentation, ZeroNoiseCopiesAreTheFrameItself) {
  const LandmarkMap map = random_map(1);
  const std::vector<uint8_t> words = keypoint_words(map, random_vocabulary(8, kBytes, 2));
  const FrameKeypoints frame = map_frame_keypoints(map, 2, words);
  AugmentNoise none;
  std::vector<int32_t> index;
  const FrameKeypoints copy = augmented_frame(frame, 2, map.frames[2].first_keypoint, none, 3, &index);
  EXPECT_EQ(copy.x, frame.x);
  EXPECT_EQ(copy.y, frame.y);
  EXPECT_EQ(copy.scale, frame.scale);
  EXPECT_EQ(copy.word, frame.word);
  for (int32_t i = 0; i < frame.size(); ++i) EXPECT_EQ(index[i], i);
}

// The draws have the noise's statistics (known answers within sampling error of ~20,000 draws),
// the rotation is one angle for the whole frame, and a copy depends on (seed, keypoint, copy) only.
TEST(Augmentation, CopiesHaveTheNoiseStatisticsAndDependOnSeedKeypointAndCopyOnly) {
  const LandmarkMap map = random_map(2, 80, 250);
  const std::vector<uint8_t> words = keypoint_words(map, random_vocabulary(8, kBytes, 3));
  AugmentNoise noise = some_noise();
  noise.rotation_rad = 0.0;
  int64_t kept = 0, total = 0;
  double sum_dx2 = 0.0, sum_log2 = 0.0;
  int64_t moved = 0;
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    const FrameKeypoints frame = map_frame_keypoints(map, f, words);
    const int64_t first = map.frames[f].first_keypoint;
    std::vector<int32_t> index;
    const FrameKeypoints copy = augmented_frame(frame, f, first, noise, 1, &index);
    for (int32_t i = 0; i < frame.size(); ++i) {
      ++total;
      ASSERT_EQ(index[i] >= 0, augmented_keypoint_kept(noise, first + i, 1));
      if (index[i] < 0) continue;
      ++kept;
      const int32_t j = index[i];
      EXPECT_EQ(copy.word[j], frame.word[i]);
      const double dx = (copy.x[j] - frame.x[i]) / frame.scale[i];
      const double dy = (copy.y[j] - frame.y[i]) / frame.scale[i];
      sum_dx2 += dx * dx + dy * dy;
      const double lr = std::log(static_cast<double>(copy.scale[j]) / frame.scale[i]);
      sum_log2 += lr * lr;
      ++moved;
    }
  }
  EXPECT_NEAR(static_cast<double>(kept) / static_cast<double>(total), 0.7, 0.01);
  EXPECT_NEAR(std::sqrt(sum_dx2 / (2.0 * static_cast<double>(moved))), 0.2, 0.004);
  EXPECT_NEAR(std::sqrt(sum_log2 / static_cast<double>(moved)), 0.15, 0.003);

  // Rotation: one angle per frame (distances between keypoints kept), different between frames.
  AugmentNoise rot;
  rot.rotation_rad = 0.3;
  rot.seed = 5;
  std::set<double> angles;
  for (frame_t f = 0; f < 6; ++f) {
    const FrameKeypoints frame = map_frame_keypoints(map, f, words);
    std::vector<int32_t> index;
    const FrameKeypoints copy = augmented_frame(frame, f, map.frames[f].first_keypoint, rot, 2, &index);
    ASSERT_EQ(copy.size(), frame.size());
    for (int32_t i = 1; i < frame.size(); ++i) {
      const double d0 = std::hypot(frame.x[i] - frame.x[0], frame.y[i] - frame.y[0]);
      const double d1 = std::hypot(copy.x[i] - copy.x[0], copy.y[i] - copy.y[0]);
      ASSERT_NEAR(d1, d0, 1e-5);
    }
    angles.insert(std::atan2(copy.y[0], copy.x[0]) - std::atan2(frame.y[0], frame.x[0]));
  }
  EXPECT_EQ(angles.size(), 6u);

  // Same (seed, frame, copy): same copy; another copy or seed: another.
  const FrameKeypoints frame = map_frame_keypoints(map, 7, words);
  const int64_t first = map.frames[7].first_keypoint;
  std::vector<int32_t> i1, i2, i3, i4;
  const FrameKeypoints a = augmented_frame(frame, 7, first, noise, 1, &i1);
  const FrameKeypoints b = augmented_frame(frame, 7, first, noise, 1, &i2);
  const FrameKeypoints c = augmented_frame(frame, 7, first, noise, 2, &i3);
  AugmentNoise other = noise;
  other.seed = 12;
  const FrameKeypoints d = augmented_frame(frame, 7, first, other, 1, &i4);
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(i1, i2);
  EXPECT_NE(i1, i3);
  EXPECT_NE(i1, i4);
  EXPECT_NE(a.x, c.x);
}

// Augmented rows equal the brute-force embedding of the copy's frame, for any thread count and
// for a rank's subset of dims; copy-0 rows are unchanged by the copies beside them.
TEST(Augmentation, FeatureRowsEqualTheBruteForceEmbeddingOfTheCopy) {
  const LandmarkMap map = random_map(3);
  const Vocabulary vocab = random_vocabulary(8, kBytes, 4);
  const ContextRegions regions = small_regions();
  const AugmentNoise noise = some_noise();
  Rng rng(9);
  std::vector<int64_t> samples, plain_samples;
  FeatureBuildOptions options;
  options.augment = noise;
  while (samples.size() < 400) {
    const int64_t k = static_cast<int64_t>(rng.below(map.keypoints.size()));
    const int32_t copy = static_cast<int32_t>(rng.below(3));
    if (copy > 0 && !augmented_keypoint_kept(noise, k, copy)) continue;
    samples.push_back(k);
    options.copies.push_back(copy);
    if (copy == 0) plain_samples.push_back(k);
  }
  const FeatureMatrix m = build_training_features(map, regions, vocab, samples, options);
  const EmbeddingLayout layout = embedding_layout(map, regions, vocab);
  const std::vector<uint8_t> words = keypoint_words(map, vocab);
  const std::vector<frame_t> frame_of = keypoint_frames(map);
  std::vector<uint8_t> row(static_cast<size_t>(layout.num_context_dims()));
  int64_t copies = 0;
  for (int64_t i = 0; i < m.num_samples; ++i) {
    const int64_t kp = samples[i];
    const frame_t f = frame_of[kp];
    const int64_t first = map.frames[f].first_keypoint;
    FrameKeypoints frame = map_frame_keypoints(map, f, words);
    int32_t k = static_cast<int32_t>(kp - first);
    if (options.copies[i] > 0) {
      std::vector<int32_t> index;
      frame = augmented_frame(frame, f, first, noise, options.copies[i], &index);
      k = index[k];
      ASSERT_GE(k, 0);
      ++copies;
    }
    embed_context_brute_force(regions, 8, frame, k, row.data());
    for (int32_t d = 0; d < m.num_dims; ++d) {
      const uint8_t expected =
          layout.is_context(d) ? row[d] : static_cast<uint8_t>(descriptor_bit(map.descriptor(kp), layout.bit_of(d)));
      ASSERT_EQ(m.column(d)[i], expected) << "sample " << i << " copy " << options.copies[i] << " dim " << d;
    }
  }
  EXPECT_GT(copies, 200);

  options.num_threads = 3;
  const FeatureMatrix three = build_training_features(map, regions, vocab, samples, options);
  EXPECT_EQ(three.data, m.data);
  for (int32_t d = 0; d < m.num_dims; d += 5) options.dims.push_back(d);
  const FeatureMatrix part = build_training_features(map, regions, vocab, samples, options);
  for (int32_t c = 0; c < part.num_stored_columns(); ++c) {
    ASSERT_TRUE(std::equal(part.column(c), part.column(c) + part.num_samples, m.column(options.dims[c])));
  }
  // A copy whose own keypoint is dropped is refused.
  for (int64_t k = 0;; ++k) {
    if (augmented_keypoint_kept(noise, k, 1)) continue;
    FeatureBuildOptions bad;
    bad.augment = noise;
    bad.copies = {1};
    EXPECT_THROW(build_training_features(map, regions, vocab, {k}, bad), Error);
    break;
  }
}

// A map whose noise is known: landmarks seen from every frame, each observation tracked with
// probability 0.6, pixel noise of 0.05 keypoint sizes per axis, keypoint size proportional to
// focal length / depth times exp(N(0, 0.1^2)); two cameras whose focal lengths differ by more than
// the repeatability test's size factor, so a size predicted without them fails between frames. Of the observations not
// tracked, half are still detected (an untracked keypoint at the landmark: matching failed), so the detector repeats
// 0.6 + 0.4 x 0.5 = 0.8 of them; 1,500 untracked clutter keypoints a frame at random places and sizes test the chance
// correction.
TEST(Augmentation, MeasuredMapNoiseRecoversKnownNoise) {
  Rng rng(21);
  LandmarkMap map;
  map.descriptor_bytes = kBytes;
  Camera wide, narrow;
  wide.width = narrow.width = 640;
  wide.height = narrow.height = 480;
  wide.params = {350, 350, 320, 240};
  narrow.params = {900, 900, 320, 240};
  map.cameras = {wide, narrow};
  map.sessions = {MapSession{"map", SessionKind::kMap}};
  for (int l = 0; l < 400; ++l) {
    Landmark lm;
    lm.position = Eigen::Vector3d(rng.uniform(-2, 2), rng.uniform(-1.5, 1.5), rng.uniform(4, 8));
    map.landmarks.push_back(lm);
  }
  std::vector<double> true_size(map.landmarks.size());
  for (double& s : true_size) s = rng.uniform(0.05, 0.15);
  int64_t possible = 0, tracked_observations = 0;
  for (int f = 0; f < 40; ++f) {
    MapFrame frame;
    frame.name = std::to_string(f);
    frame.camera = f % 2;
    const Camera& cam = map.cameras[frame.camera];
    frame.cam_from_world.translation = Eigen::Vector3d(rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), 0);
    frame.first_keypoint = static_cast<int64_t>(map.keypoints.size());
    for (landmark_t l = 0; l < static_cast<landmark_t>(map.landmarks.size()); ++l) {
      const Eigen::Vector3d in_cam = frame.cam_from_world * map.landmarks[l].position;
      Eigen::Vector2d px;
      if (!cam.project(in_cam, &px) || px.x() < 0 || px.x() >= 640 || px.y() < 0 || px.y() >= 480) continue;
      ++possible;
      const bool tracked = rng.uniform() < 0.6;
      const bool detected = tracked || rng.uniform() < 0.5;
      const double size = cam.mean_focal_length() * true_size[l] / in_cam.z() * std::exp(0.1 * rng.normal());
      const double x = px.x() + 0.05 * size * rng.normal(), y = px.y() + 0.05 * size * rng.normal();
      if (!detected) continue;
      map.keypoints.push_back(Keypoint{static_cast<float>(x), static_cast<float>(y), static_cast<float>(size), -1.f});
      map.keypoint_landmark.push_back(tracked ? l : kInvalidLandmarkId);
      tracked_observations += tracked;
    }
    for (int c = 0; c < 1500; ++c) {
      map.keypoints.push_back(Keypoint{static_cast<float>(rng.uniform(0, 640)), static_cast<float>(rng.uniform(0, 480)),
                                       static_cast<float>(rng.uniform(3, 20)), -1.f});
      map.keypoint_landmark.push_back(kInvalidLandmarkId);
    }
    frame.num_keypoints = static_cast<int32_t>(map.keypoints.size() - frame.first_keypoint);
    map.frames.push_back(frame);
  }
  const MapNoiseEstimate m = measure_map_noise(map, 40);
  EXPECT_GT(possible, 10000);
  EXPECT_NEAR(m.reobservation_rate, 0.6, 0.02);
  EXPECT_NEAR(m.repeatability, 0.8, 0.02);
  // The clutter is found beside many projections; without the correction the rate would be
  // 0.8 + 0.2 x chance.
  EXPECT_GT(m.chance_rate, 0.15) << m.repeatability;
  EXPECT_LT(m.chance_rate, 0.5);
  EXPECT_GT(m.repeat_tests, 10000);
  EXPECT_NEAR(m.position_sigma, 0.05, 0.004);
  EXPECT_NEAR(m.scale_sigma, 0.1, 0.005);
  EXPECT_EQ(m.residuals, tracked_observations);

  // A map without tracks: nothing to measure, no noise.
  const MapNoiseEstimate none = measure_map_noise(random_map(4));
  EXPECT_EQ(none.reobservation_rate, 1.0);
  EXPECT_EQ(none.repeatability, 1.0);
  EXPECT_EQ(none.position_sigma, 0.0);
  EXPECT_EQ(none.scale_sigma, 0.0);
}

TEST(Augmentation, BadNoiseIsRefused) {
  AugmentNoise n;
  n.dropout = 1.0;
  EXPECT_THROW(n.check(), Error);
  n.dropout = 0.2;
  n.position_sigma = std::nan("");
  EXPECT_THROW(n.check(), Error);
  n.position_sigma = 0.1;
  n.scale_sigma = -0.1;
  EXPECT_THROW(n.check(), Error);
  n.scale_sigma = 0.1;
  EXPECT_NO_THROW(n.check());
}

}  // namespace
}  // namespace lmb
